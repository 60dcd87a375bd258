"""Fuzzing the readers of option strings (issue 21): ``--fap``/``--viseme``/``--expression``,
MIAP and FAP names, ``--size``, ``--camera``, ``--background``, ``analyze --faps``, ``encode
--faps``, ``--seed``. Whatever the string, the only exception is the reader's VttsError (or
argparse's ArgumentTypeError for a type function); what is accepted reads back the same when
written as the reader's own syntax.
"""

from __future__ import annotations

import argparse
import math

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from vtts.analysis.unknowns import parse_unknowns
from vtts.api.options import parse_assignments
from vtts.api.options import parse_size as _size
from vtts.cli.options import seed_type as _seed
from vtts.errors import AnalysisError, FapError, RenderError
from vtts.face.miap import Miap, face_params
from vtts.fap.coding import fap_set
from vtts.render import Camera
from vtts.render.color import TRANSPARENT, parse_background

from .fuzzing import examples
from .hostile import DATA, INTERESTING, mutate, mutations

FUZZ = settings(
    max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow]
)

WORDS = [
    "19", "3", "68", "69", "0", "1", "2", "-1", "+5", "+-5", "open_jaw", "head_pitch", "viseme",
    "viseme3", "viseme 3", "viseme-3", "viseme_-1", "expression", "joy", "smile", "expression 7",
    "tx", "tz", "paper17", "table1", "all", "low", "3-13", "13-3", "0-99", "9" * 30, "9" * 5000,
    "²", "٣", "3²", "1e999", "nan", "inf", "-0", "0x10", "1_0", " ", "=", ",", "-", "p", "A:",
]  # fmt: skip
words = st.sampled_from(WORDS)
#: An option value: a few words and separators, or any short text, or a mutated real value.
option_text = st.one_of(
    st.lists(st.one_of(words, st.sampled_from(INTERESTING)), max_size=6).map("".join),
    st.lists(words, max_size=4).map(",".join),
    st.text(max_size=30),
    st.builds(mutate, st.sampled_from(["19=512,open_jaw=300", "352x288", "400,400,176,144"]),
              mutations),
)  # fmt: skip


@FUZZ
@given(option_text)
@example("²")  # int('²') raised ValueError: str.isdigit() is true for superscripts
@example("9" * 5000)  # int() refuses more than 4,300 digits with a ValueError
@example("+-5")  # lstrip('+-') then int('+-5')
@example("viseme ²")
@example("expression ²")
def test_miap_names(text: str) -> None:
    try:
        miap = Miap.parse(text)
    except FapError as e:
        assert e.message
        return
    assert Miap.parse(miap.key) == miap
    assert Miap.parse(miap.name if miap.kind != "viseme" else f"viseme {miap.number}") == miap


@FUZZ
@given(option_text, st.sampled_from(["FAP", "viseme", "expression"]))
@example("²=1", "FAP")
@example("9" * 5000 + "=1", "FAP")
def test_pose_assignments(text: str, what: str) -> None:
    """What ``vtts pose``/``render`` do with ``--fap``, ``--viseme`` and ``--expression``."""
    bounds = (-1e6, 1e6) if what == "FAP" else (0.0, 1.0)
    default = None if what == "FAP" else 1.0
    try:
        values = parse_assignments(text, what, default, bounds=bounds)
        face_params(
            values if what == "FAP" else None,
            visemes=values if what == "viseme" else None,
            expressions=values if what == "expression" else None,
        )
    except FapError as e:
        assert e.message
        return
    for v in values.values():
        assert math.isfinite(v) and bounds[0] <= v <= bounds[1]


@FUZZ
@given(option_text)
@example("²x288")  # int('²') after str.isdigit()
@example("9" * 5000 + "x288")
def test_size(text: str) -> None:
    try:
        w, h = _size(text)
    except RenderError as e:
        assert e.message
        return
    assert _size(f"{w}x{h}") == (w, h)


@FUZZ
@given(option_text)
def test_camera(text: str) -> None:
    try:
        cam = Camera.parse(text)
    except RenderError as e:
        assert e.message
        return
    assert all(math.isfinite(v) for v in (cam.fx, cam.fy, cam.cx, cam.cy))


@FUZZ
@given(option_text)
def test_background(text: str) -> None:
    try:
        color = parse_background(text)
    except RenderError as e:
        assert e.message
        return
    if color != TRANSPARENT:
        assert all(0 <= c <= 1 for c in color)
        assert parse_background(",".join(repr(c) for c in color)) == color


@FUZZ
@given(option_text)
@example("9" * 5000)
@example("3-" + "9" * 5000)
@example("²")
def test_analyze_faps(text: str) -> None:
    try:
        unknowns = parse_unknowns(text)
    except AnalysisError as e:
        assert e.message
        return
    assert parse_unknowns(",".join(map(str, unknowns))) == unknowns


@FUZZ
@given(option_text)
@example("9" * 5000)
@example("3-" + "9" * 5000)
def test_encode_faps(text: str) -> None:
    try:
        faps = fap_set(text)
    except FapError as e:
        assert e.message
        return
    assert faps and fap_set(",".join(map(str, faps))) == faps


@FUZZ
@given(option_text)
def test_seed(text: str) -> None:
    try:
        seed = _seed(text)
    except argparse.ArgumentTypeError as e:
        assert str(e)
        return
    assert 0 <= seed < 2**63


# ---- every option of every command ---------------------------------------------------------------


def _commands() -> list[tuple[str, argparse.ArgumentParser]]:
    """``(name, parser)`` of every subcommand of ``vtts`` and ``adi``."""
    from adt_tools.cli import build_parser as adi_parser
    from vtts.cli._main import build_parser as vtts_parser

    out = []
    for tool, parser in (("vtts", vtts_parser()), ("adi", adi_parser())):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                out += [(f"{tool} {n}", p) for n, p in action.choices.items()]
    return out


COMMANDS = _commands()
#: ``(command, option)`` for every option of every command that takes one value.
OPTIONS = [
    (name, action.option_strings[-1])
    for name, parser in COMMANDS
    for action in parser._actions
    if action.option_strings and action.nargs in (None, "?")  # store_true and help take none
]  # fmt: skip
HOSTILE = ["--", "-", "", "nan", "-inf", "1e999", "1e308", "-1", "0", "9" * 5000, "²", "\x00"]


def _parse(name: str, option: str, value: str) -> object:
    """What the command's parser makes of ``OPTION=VALUE`` (its positionals given as ``x`` and
    its other options made optional): the option's value, or the exit status of a usage error."""
    import copy
    import io
    from contextlib import redirect_stderr

    parser = copy.deepcopy(dict(COMMANDS)[name])
    positionals = []
    for action in parser._actions:
        if action.option_strings:
            action.required = False
        elif action.nargs not in ("?", "*"):
            positionals.append("x")
    dest = next(a.dest for a in parser._actions if option in a.option_strings)
    try:
        with redirect_stderr(io.StringIO()):
            ns = parser.parse_args([f"{option}={value}", *positionals])
    except SystemExit as e:
        return e.code
    return getattr(ns, dest)


@pytest.mark.parametrize("name, option", OPTIONS, ids=[f"{n} {o}" for n, o in OPTIONS])
def test_every_option_takes_dashes_as_a_value(name: str, option: str) -> None:
    """``--size=--`` gave the command an empty list (argparse strips the ``--`` and skips the
    type): a traceback where it met a string, or the option silently ignored (``--camera``).
    Every option now takes ``'--'`` as its value, judged by its type like any other."""
    value = _parse(name, option, "--")
    assert value == 2 or isinstance(value, str | int | float | list) and value != [], value
    if isinstance(value, list):  # an option that collects (--fap, --viseme): '--' is collected
        assert value[-1] == "--" or not isinstance(value[-1], list)


@settings(max_examples=examples(60), deadline=None)
@given(st.sampled_from(OPTIONS), st.one_of(st.sampled_from(HOSTILE), option_text))
def test_every_option_takes_any_value(option: tuple[str, str], value: str) -> None:
    """Whatever the value, an option's type gives a value or a usage error, never an exception."""
    got = _parse(*option, value)
    assert got != []


_HEAD = str(DATA / "models" / "head.wrl")
_JOY = str(DATA / "fap" / "xface-joy.fap")


@pytest.mark.parametrize(
    "argv, message",
    [
        (["render", "--model", _HEAD, "--size=--", "-o", "x.png"], "--size takes WIDTHxHEIGHT"),
        (["say", "hi", "--model=--", "--wav-out", "x.wav"], "no model '--'"),
        (["render", "--model", _HEAD, "--fap=--", "-o", "x.png"], "FAP '--' needs a value"),
        (["render", "--model", _HEAD, "--camera=--", "-o", "x.png"], "--camera takes four"),
        (
            ["say", "hi", "--model", _HEAD, "--fps=--", "-o", "x.mp4"],
            "--fps: invalid float value: '--'",
        ),
        (["encode", _JOY, "--rate=--", "-o", "x.fbs"], "--rate: expected a number, got '--'"),
        (["play", _JOY, "--model", _HEAD, "--size=--", "-o", "x.mp4"], "--size takes"),
    ],
    ids=lambda v: v if isinstance(v, str) else None,
)
def test_dashes_as_a_value_are_a_clear_error(tmp_path, monkeypatch, capsys, argv, message):
    """Each was a traceback (``--camera=--`` was ignored: the picture was written)."""
    from vtts.cli import main

    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err
    assert code in (1, 2) and message in err and "Traceback" not in err, err
    assert not any(tmp_path.iterdir())
