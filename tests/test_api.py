"""The library API of the commands (vtts.api, exported from vtts): options checked when they are
made, with the command's messages; say, render, encode and decode from Python; batch jobs checked
against the options dataclasses, without argparse."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import vtts
from vtts.errors import AnalysisError, FapError, RenderError, VttsError

ROOT = Path(__file__).parents[1]
JOY = ROOT / "samples" / "fap" / "xface-joy.fap"
SAMPLE = ROOT / "samples" / "candide3.wrl"


@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (lambda: vtts.SayOptions(text="Hi.", model="cybatt"), RenderError, "nothing to write"),
        (
            lambda: vtts.SayOptions(text="Hi.", model="cybatt", output="a.mp4", fps=0),
            RenderError,
            "--fps must be within 0–240, got 0",
        ),
        (
            lambda: vtts.SayOptions(text="Hi.", model="cybatt", output="a.mp4", seed=-1),
            RenderError,
            "--seed -1 must be within 0 to 2**63 - 1",
        ),
        (
            lambda: vtts.SayOptions(text="Hi.", model="cybatt", output="a.png"),
            RenderError,
            "-o writes a video",
        ),
        (
            lambda: vtts.SayOptions(text="Hi.", model="cybatt", output="a.mp4", layout="ring"),
            RenderError,
            "--layout must be one of row, room, got 'ring'",
        ),
        (
            lambda: vtts.SayOptions(text="Hi.", model="cybatt", output="a.mp4", engine="sam"),
            RenderError,
            "--engine must be one of espeak, festival, piper, got 'sam'",
        ),
        (
            lambda: vtts.SayOptions(text="Hi.", output="a.mp4"),
            VttsError,
            "no model: give one or more",
        ),
        (
            lambda: vtts.PlayOptions(stream="x.fap", model="cybatt", output="a.mp4", fps=300),
            RenderError,
            "--fps must be within 0–240, got 300",
        ),
        (
            lambda: vtts.PlayOptions(stream="-", model="cybatt", output="a.mp4", web="w"),
            RenderError,
            "--web need the whole stream",
        ),
        (
            lambda: vtts.RenderOptions(model="cybatt", background="mauvish"),
            RenderError,
            "not a background: 'mauvish'",
        ),
        (
            lambda: vtts.AnalyzeOptions(video="-", output="a.fap"),
            AnalysisError,
            "give --size WIDTHxHEIGHT",
        ),
        (
            lambda: vtts.AnalyzeOptions(video="v.mp4", output="a.fap", step=0),
            AnalysisError,
            "--step must be a whole number ≥ 1, got 0",
        ),
        (
            lambda: vtts.EncodeOptions(input="a.fap", output="a.fbs", quantizer=0),
            FapError,
            "--quantizer must be a positive number, got 0",
        ),
    ],
)
def test_options_are_checked_when_made(make, error, message):
    with pytest.raises(error) as e:
        make()
    assert message in e.value.message


def test_a_pose_request_names_the_bad_item():
    options = vtts.RenderOptions(model="cybatt", fap="open_jaw=lots")
    with pytest.raises(FapError, match="FAP 'open_jaw': 'lots' is not a number"):
        vtts.render_still(options)


def test_render_returns_the_frame_without_writing(tmp_path):
    joy = vtts.render_still(vtts.RenderOptions(model="cybatt", size="64x48", expression="joy"))
    neutral = vtts.render_still(vtts.RenderOptions(model="cybatt", size="64x48"))
    assert joy.output is None and joy.frame.shape == (48, 64, 3)
    assert joy.frame.dtype == np.uint8 and not np.array_equal(joy.frame, neutral.frame)
    written = vtts.render_still(
        vtts.RenderOptions(
            model="cybatt", size="64x48", expression="joy", output=str(tmp_path / "j.png")
        )
    )
    assert written.output == tmp_path / "j.png" and written.output.stat().st_size > 0
    assert np.array_equal(written.frame, joy.frame)


def test_say_to_a_path_from_python(tmp_path):
    out, wav = tmp_path / "hi.mp4", tmp_path / "hi.wav"
    said = vtts.say(
        vtts.SayOptions(
            text="Hi there.", model="cybatt", size="160x120", output=str(out), wav_out=str(wav)
        )  # fmt: skip
    )
    assert said.written == [str(out), str(wav)]
    assert out.stat().st_size > 0 and wav.stat().st_size > 0
    assert said.n_frames == pytest.approx(said.duration * said.fps, abs=1.5)
    assert said.audio.dtype == np.int16 and len(said.audio) == pytest.approx(
        said.duration * said.rate, abs=said.rate / 100
    )


def test_say_reports_a_bad_bookmark(tmp_path):
    wav = tmp_path / "x.wav"
    options = vtts.SayOptions(text="Hello <frown> you.", model="cybatt", wav_out=str(wav))
    with pytest.raises(VttsError, match="unknown bookmark <frown>"):
        vtts.say(options)
    assert not wav.exists()


def test_encode_and_decode_from_python(tmp_path):
    fbs, fap = tmp_path / "joy.fbs", tmp_path / "joy.fap"
    encoded = vtts.encode(vtts.EncodeOptions(input=str(JOY), output=str(fbs), quantizer=4))
    assert fbs.read_bytes() == encoded.data and encoded.header.n_frames > 10
    key, error, step = encoded.max_error()
    assert error <= step / 2 + 1e-9
    decoded = vtts.decode(vtts.DecodeOptions(input=str(fbs), output=str(fap)))
    assert decoded.n_frames == encoded.header.n_frames and fap.is_file()
    assert vtts.read_stream(fbs).n_frames == decoded.n_frames


def test_check_reports_each_file(tmp_path):
    good, missing = vtts.check([SAMPLE, tmp_path / "none.wrl"])
    assert good.ok and good.summary == "7 nodes, 184 triangles"
    assert not missing.ok and missing.error.message == "no such file"


def test_import_vtts_imports_no_command_until_one_is_used():
    code = (
        "import sys, vtts\n"
        "assert not any(m.startswith(('vtts.api', 'vtts.cli')) for m in sys.modules), 'early'\n"
        "vtts.SayOptions\n"
        "assert 'vtts.api.say' in sys.modules and 'vtts.cli' not in sys.modules\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr


def test_a_bad_batch_job_is_refused_without_argparse(tmp_path):
    code = (
        "import sys\n"
        "from vtts.batch.jobs import JobError, parse_job\n"
        "try:\n"
        "    parse_job({'say': 'Hi.', 'model': 'cybatt', 'fps': 500, 'output': 'a.mp4'}, 'out')\n"
        "except JobError as e:\n"
        "    print(e.message)\n"
        "print('argparse' in sys.modules, any(m.startswith('vtts.cli') for m in sys.modules))\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=tmp_path
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == ["vtts say: --fps must be within 0–240, got 500", "False False"]
