"""What the user gives never becomes markup or a terminal command (issue 45): a model's name in
the web player's page, control characters in the command line's messages."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from .hostile import DATA, run_bounded
from .in_process import vtts

HEAD = DATA / "models" / "head.wrl"
JOY = DATA / "fap" / "xface-joy.fap"
ESC = "\x1b[31m"


@pytest.mark.parametrize("name", ["<!--<script>", "<script>alert(1)<", "a&amp;b", "x]]>--><b>"])
def test_a_model_name_stays_text_in_the_web_page(tmp_path, name):
    for suffix in (".wrl", ".adt"):
        shutil.copy(HEAD.with_suffix(suffix), tmp_path / f"{name}{suffix}")
    # in this process: the page is the library's (head.wrl is below the model cache's 1 MB)
    args = ("play", str(JOY), "--model", f"{name}.wrl", "--web", "w", "--quiet")
    r = vtts(*args, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "w" / "index.html").read_text(encoding="utf-8")
    config = re.search(r'id="vtts-config">(.*?)</script>', page, re.S)[1]
    assert not set("<>&") & set(config)  # nothing in it an HTML parser reads as markup
    assert json.loads(config)["heads"] == [name]
    assert "<!--" not in page and page.count("</script>") == 3  # import map, settings, player


def test_the_settings_json_escapes_what_html_reads():
    from vtts.export.web import script_json

    text = script_json({"a": "<!--<script></script>&\u2028"})
    assert not set("<>&\u2028") & set(text)
    assert json.loads(text) == {"a": "<!--<script></script>&\u2028"}


@pytest.mark.parametrize(
    "args",
    [
        ["voices", ESC],
        ["render", "--model", ESC, "-o", "x.png"],
        ["render", "--model", "cybatt", "-o", "x.png", "--bogus", ESC],
        ["check", f"{ESC}.wrl"],
        ["info", f"{ESC}.wrl"],
        ["play", f"{ESC}.fap", "--model", "cybatt", "-o", "x.mp4"],
    ],
    ids=["voices", "error", "argparse", "check", "info", "play"],
)
def test_control_characters_in_what_vtts_echoes_are_escaped(tmp_path, args):
    r = run_bounded("vtts", *args, cwd=tmp_path)  # what reaches the terminal: a process's
    assert r.returncode != 0
    assert "\x1b" not in r.stderr + r.stdout
    assert "\\x1b[31m" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize(
    "args",
    [["fit", f"{ESC}.png", "-o", "x.wrl"], ["fit", "p.png", "-o", f"{ESC}.obj"],
     ["show", f"{ESC}.adt"], ["import", "a.glb", "-o", "x.wrl", "--bogus", ESC]],
    ids=["fit", "output", "show", "argparse"],
)  # fmt: skip
def test_control_characters_in_what_adi_echoes_are_escaped(tmp_path, args):
    r = run_bounded("adi", *args, cwd=tmp_path)
    assert r.returncode != 0
    assert "\x1b" not in r.stderr + r.stdout
    assert "\\x1b[31m" in r.stderr and "Traceback" not in r.stderr


def test_echo_escapes_each_line_and_keeps_the_line_breaks(capsys):
    from vtts.messages import echo

    echo(f"a{ESC}\nb\x07", "c")
    assert capsys.readouterr().out == "a\\x1b[31m\nb\\x07 c\n"


def test_the_written_files_are_named_escaped(tmp_path):
    out = Path(f"{ESC}.png")
    args = ("render", "--model", "cybatt", "--size", "32x24", "-o", str(out))
    r = vtts(*args, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "\x1b" not in r.stdout and "wrote \\x1b[31m.png" in r.stdout
    assert (tmp_path / out).is_file()


@pytest.mark.parametrize("dry", [True, False], ids=["dry-run", "run"])
def test_a_bad_batch_line_is_echoed_escaped(tmp_path, dry):
    jobs = tmp_path / "jobs.jsonl"
    jobs.write_text(json.dumps({"say": "hi", "model": "cybatt", ESC: 1}) + "\n")
    args = ("batch", str(jobs), "--out", "out", *(["--dry-run"] if dry else []))
    r = vtts(*args, cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "\x1b" not in r.stderr + r.stdout
    assert "has no option '\\x1b[31m'" in r.stderr


def test_a_progress_bar_names_the_file_escaped():
    from vtts.render.output import progress

    with progress(3, f"analyzing {ESC}.mp4", quiet=True) as bar:
        assert bar.description == "analyzing \\x1b[31m.mp4"
