"""``vtts analyze``: bad input is a clear error before any estimation; a run writes its files."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vtts.api.analyze import QUANTIZER

from .. import in_process

DATA = Path(__file__).parents[1] / "data"
HEAD = str(DATA / "models" / "head.wrl")


def vtts(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("vtts")
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=300, cwd=cwd)


def _inputs(root: Path) -> None:
    """Inputs of the bad-input cases, all in ``root/in``."""
    d = root / "in"
    frame = np.full((48, 64, 3), 120, np.uint8)
    (d / "ok").mkdir(parents=True)
    (d / "mixed").mkdir()
    (d / "empty").mkdir()
    for name in ("f1.png", "f2.png"):
        Image.fromarray(frame).save(d / "ok" / name)
        Image.fromarray(frame).save(d / "mixed" / name)
    Image.fromarray(np.zeros((30, 40, 3), np.uint8)).save(d / "mixed" / "f10.png")
    (d / "file.txt").write_text("not a video")


@pytest.mark.parametrize(
    "args, fragments",
    [
        (["{in}/none.mp4"], ["none.mp4: error: no such video file or PNG folder"]),
        (["{in}/mixed"], ["f10.png: error:", "40x30", "64x48", "f1.png"]),
        (["{in}/empty"], ["empty: error: the folder has no .png files"]),
        (["{in}/file.txt"], ["file.txt: error: cannot read the video"]),
        (["{in}/ok", "--faps", "1,3"], ["--faps item '1'", "high-level"]),
        (["{in}/ok", "--faps", "3,foo"], ["--faps item 'foo'", "not a FAP"]),
        (["{in}/ok", "--faps", "3,12,3"], ["--faps item '3'", "already listed"]),
        (["{in}/ok", "--faps", "paper17,tx"], ["--faps item 'tx'", "by 'paper17'"]),
        (["{in}/ok", "--faps", "99"], ["--faps item '99'", "out of range"]),
        (["{in}/ok", "--camera", "400,400,176"], ["--camera takes four numbers"]),
        (["{in}/ok", "--camera", "0,400,176,144"], ["camera fx must be a positive"]),
        (["{in}/ok", "--step", "0"], ["--step must be"]),
        (["{in}/ok", "--at-rate"], ["--at-rate analyzes the frames of --rate"]),
        (["{in}/ok", "--at-rate", "--rate", "5", "--step", "2"], ["and no --step"]),
        (["{in}/ok", "--fps", "0"], ["--fps must be"]),
        (["{in}/ok", "--quantizer", "0"], ["--quantizer must be a number within 0–1000"]),
        (["{in}/ok", "--model", HEAD, "--model", HEAD], ["one model"]),
        (["{in}/ok", "-o", "{in}/file.txt/x.fap"], ["x.fap: error: cannot write here", "file"]),
        (["{in}/ok", "-o", "{in}/ok"], ["error: cannot write here: it is a folder"]),
        (
            ["{in}/ok", "--report", "{in}/file.txt"],
            ["file.txt: error: the report folder is a file"],
        ),
        (["{in}/ok", "--model", "{in}/none.wrl"], ["no model"]),
    ],
)
def test_bad_input_is_a_clear_error(tmp_path, args, fragments):
    """In this process (test_bad_input_ends_the_process_… runs the command)."""
    _bad_input(tmp_path, args, fragments, in_process.vtts)


def test_bad_input_ends_the_process_with_a_clear_error(tmp_path):
    _bad_input(tmp_path, ["{in}/mixed"], ["f10.png: error:", "40x30", "64x48", "f1.png"], vtts)


def _bad_input(tmp_path: Path, args: list[str], fragments: list[str], run) -> None:
    """``vtts analyze ARGS`` (``run``) fails with ``fragments`` on stderr and writes nothing."""
    _inputs(tmp_path)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    argv = [a.replace("{in}", str(tmp_path / "in")) for a in args]
    if "--model" not in argv:
        argv += ["--model", HEAD]
    if "-o" not in argv:
        argv += ["-o", str(tmp_path / "out" / "x.fap")]
    r = run("analyze", *argv)
    assert r.returncode == 1, (r.returncode, r.stderr)
    for fragment in fragments:
        assert fragment in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    after = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    assert after == before  # nothing written, not even a temporary file or the out folder


def test_help_lists_the_options():
    r = vtts("analyze", "--help")
    assert r.returncode == 0
    for option in ("--model", "-o", "--faps", "--camera", "--step", "--fps", "--report", "--fbs",
                   "--steps", "--quantizer"):  # fmt: skip
        assert option in r.stdout
    assert f"(default {QUANTIZER:g}:" in " ".join(r.stdout.split())  # the library's default


# ---- a whole run (needs the estimator) -----------------------------------------------------------


@pytest.fixture(scope="module")
def rendered_frames(tmp_path_factory) -> Path:
    """Three frames of the test head at 176x144, the head pitching (FAP 48, AU = 1e-5 rad),
    rendered as `vtts play` renders video frames (no supersampling)."""
    from vtts.face import N_PARAMS, load_model
    from vtts.render.output import write_png
    from vtts.render.renderer import FaceRenderer

    d = tmp_path_factory.mktemp("frames")
    with FaceRenderer(load_model(HEAD), size=(176, 144)) as r:
        for i, pitch in enumerate((0, 3000, 6000)):
            p = np.zeros(N_PARAMS)
            p[47] = pitch
            write_png(d / f"frame_{i}.png", r.render(p))
    return d


def test_the_bitstream_carries_the_steps_measured_on_the_head(tmp_path, rendered_frames):
    """``-o X.fbs`` codes with the base steps measured on the model (``--steps face``, the
    default): the lip corner's (FAP 6, a few pixels of the test head) coarser than MPEG-4's,
    the head's pitch (every pixel) finer; ``--steps mpeg4`` the standard's. The runs are in this
    process; the usage error is the process's."""
    from vtts.fap.coding import read_header
    from vtts.fap.table import FAPS

    headers = {}
    for steps in ("face", "mpeg4"):
        out = tmp_path / f"{steps}.fbs"
        r = in_process.vtts("analyze", str(rendered_frames), "--model", HEAD, "-o", str(out),
                            "--faps", "6,48", "--fps", "30", "--steps", steps,
                            "--quiet")  # fmt: skip
        assert r.returncode == 0, r.stderr
        headers[steps] = read_header(out.read_bytes())
    # the coder's quantizer: the command's default (docs/analysis.md, "Measuring on people")
    assert headers["face"].quantizer == headers["mpeg4"].quantizer == QUANTIZER == 4.0
    assert headers["mpeg4"].base_steps == (FAPS[5].quant_step, FAPS[47].quant_step)
    face = dict(zip(headers["face"].low, headers["face"].base_steps, strict=True))
    assert face[6] > FAPS[5].quant_step and face[48] < FAPS[47].quant_step, face
    out = tmp_path / "q1.fbs"
    r = in_process.vtts("analyze", str(rendered_frames), "--model", HEAD, "-o", str(out),
                        "--faps", "6,48", "--fps", "30", "--quantizer", "1", "--quiet")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert read_header(out.read_bytes()).quantizer == 1.0
    r = vtts("analyze", str(rendered_frames), "--model", HEAD, "-o", str(tmp_path / "x.fbs"),
             "--steps", "even")  # fmt: skip
    assert r.returncode == 2 and "invalid choice: 'even'" in r.stderr


def test_a_run_writes_the_fap_file_the_bitstream_and_the_report(tmp_path, rendered_frames):
    from vtts.api.coding import read_stream

    out = tmp_path / "out" / "talk.fap"
    r = vtts(
        "analyze", str(rendered_frames), "--model", HEAD, "-o", str(out), "--faps", "48,tx",
        "--fps", "30", "--report", str(tmp_path / "report"), "--fbs",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    summary = r.stdout.strip().splitlines()[-1]
    assert str(out) in summary and "3 frames" in summary and "PSNR" in summary
    stream = read_stream(out)
    assert stream.n_frames == 3 and stream.fps == 30
    assert stream.mask[:, 47].all() and stream.mask.sum() == 3  # FAP 48 only: tx is not a FAP
    # the pitch the frames were rendered with, found again (within 0.1°)
    assert abs(stream.values[:, 47] - [0, 3000, 6000]).max() <= 175, stream.values[:, 47]
    coded = read_stream(out.with_suffix(".fbs"))
    assert coded.n_frames == 3
    with open(tmp_path / "report" / "frames.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [row["frame"] for row in rows] == ["0", "1", "2"]
    assert {"fap48", "tx"} <= rows[0].keys()
    assert {p.name for p in (tmp_path / "report").iterdir()} == {
        "frames.csv",
        "psnr.png",
        "faps.png",
        "side-by-side.mp4",
    }
    # camera | decoder's view | difference, one frame per estimate
    from vtts.render import probe_media

    info = probe_media(tmp_path / "report" / "side-by-side.mp4")
    frame = next(iter(Image.open(rendered_frames / sorted(os.listdir(rendered_frames))[0]).size))
    assert info.frames == 3 and info.width == 3 * frame, info
    assert sorted(p.name for p in out.parent.iterdir()) == ["talk.fap", "talk.fbs"]


# ---- the command around the estimator (a stand-in estimator, in process) -------------------------


@pytest.fixture
def fake_estimator(monkeypatch):
    """Replace the tracking by a stand-in: FAP k of frame i is the frame's mean + k, tx the frame
    index. Returns the list of the calls' keyword arguments."""
    import vtts.analysis.track as track
    from vtts.analysis.result import Analysis, FrameEstimate
    from vtts.analysis.unknowns import DEFAULT_UNKNOWNS
    from vtts.face import N_PARAMS
    from vtts.render import Camera

    calls: list[dict] = []

    def fake_track(
        frames, *, fps, model, step=1, camera=None, unknowns=DEFAULT_UNKNOWNS, progress=None,
        **_options,
    ):  # fmt: skip
        from vtts.analysis.frame_times import analysis_fps, analyzed

        calls.append({"fps": fps, "step": step, "camera": camera, "unknowns": tuple(unknowns)})
        rate = _options.get("rate")
        if rate is not None:
            calls[-1]["rate"] = rate
        out = []
        for i, frame in enumerate(frames):
            if not analyzed(i, fps, step, rate):
                continue
            params = np.zeros(N_PARAMS)
            for u in unknowns:
                if isinstance(u, int):
                    params[u - 1] = frame.mean() + u
            tr = np.array([i, 0.0, 0.0])
            out.append(FrameEstimate(i, i / fps, params, tr, psnr=40.0 + i, face_pixels=10))
            if progress is not None:
                progress(i)
        if not out:
            from vtts.errors import AnalysisError

            raise AnalysisError("the video has no frames")
        analysis = Analysis(
            out,
            tuple(unknowns),
            analysis_fps(fps, step, rate),
            camera or Camera(1, 1, 0, 0),
            model.name,
        )
        return track.Tracked(analysis, model)

    monkeypatch.setattr(track, "track", fake_track)
    return calls


@pytest.fixture
def five_frames(tmp_path) -> Path:
    d = tmp_path / "frames"
    d.mkdir()
    for i in range(5):
        Image.fromarray(np.full((48, 64, 3), 10 * i, np.uint8)).save(d / f"f{i}.png")
    return d


def test_outputs_of_a_run(tmp_path, five_frames, fake_estimator):
    from vtts.api.coding import read_stream

    out = tmp_path / "out" / "est.fap"
    report = tmp_path / "report"
    argv = [
        "analyze", str(five_frames), "--model", HEAD, "-o", str(out), "--step", "2",
        "--faps", "3,tx", "--fps", "10", "--report", str(report), "--fbs", "--quantizer", "1",
    ]  # fmt: skip
    r = in_process.vtts(*argv)
    assert r.returncode == 0, r.stderr
    (call,) = fake_estimator
    assert call == {"fps": 10.0, "step": 2, "camera": None, "unknowns": (3, "tx")}
    stream = read_stream(out)
    assert stream.n_frames == 3 and stream.fps == 5.0 and stream.name == "frames"
    assert stream.mask.sum() == 3 and stream.mask[:, 2].all()
    np.testing.assert_array_equal(stream.values[:, 2], [3, 23, 43])  # frames 0, 2, 4
    coded = read_stream(out.with_suffix(".fbs"))
    # coded on the grid of open_jaw's MPEG-4 step (4 MNS units): within half a step
    np.testing.assert_allclose(coded.values[:, 2], [3, 23, 43], atol=2)
    assert sorted(p.name for p in report.iterdir()) == [
        "faps.png",
        "frames.csv",
        "psnr.png",
        "side-by-side.mp4",
    ]
    text = r.stdout.strip()
    assert len(text.splitlines()) == 1
    assert str(out) in text and str(out.with_suffix(".fbs")) in text and str(report) in text
    assert "3 frames at 5 fps" in text and "mean face PSNR 42.00 dB" in text


def test_the_frames_of_the_coded_rate(tmp_path, five_frames, fake_estimator):
    """``--at-rate`` analyzes the frames the coded stream shows, which it carries unresampled:
    at 10 fps and 4 Hz the frames nearest 0, 0.25, 0.5 s — 0, 3 (2.5 rounded half up) and 5,
    past the five frames: 0 and 3 (--step 2 would take 0, 2 and 4 and code them at 5 Hz)."""
    from vtts.api.coding import read_stream

    out = tmp_path / "est.fbs"
    argv = ["analyze", str(five_frames), "--model", HEAD, "-o", str(out), "--fps", "10",
            "--faps", "3", "--rate", "4", "--at-rate", "--quantizer", "1"]  # fmt: skip
    r = in_process.vtts(*argv)
    assert r.returncode == 0, r.stderr
    (call,) = fake_estimator
    assert call["rate"] == 4.0 and call["step"] == 1
    coded = read_stream(out)
    assert coded.fps == 4.0 and coded.n_frames == 2
    np.testing.assert_allclose(coded.values[:, 2], [3, 33], atol=2)  # frames 0 and 3


def test_fbs_output_and_camera(tmp_path, five_frames, fake_estimator):
    from vtts.api.coding import read_stream

    out = tmp_path / "est.fbs"
    argv = ["analyze", str(five_frames), "--model", HEAD, "-o", str(out), "--camera", "90,80,32,24"]
    r = in_process.vtts(*argv)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:4] == b"VFBS"
    assert read_stream(out).n_frames == 5
    (call,) = fake_estimator
    cam = call["camera"]
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (90, 80, 32, 24)
    assert call["fps"] == 25.0  # a folder's default rate
    from vtts.analysis.unknowns import DEFAULT_UNKNOWNS

    assert call["unknowns"] == DEFAULT_UNKNOWNS  # no --faps: the estimator's default
    assert sorted(p.name for p in tmp_path.iterdir()) == ["est.fbs", "frames"]


def test_a_failing_estimation_leaves_no_output(tmp_path, five_frames, monkeypatch):
    import vtts.analysis.track as track
    from vtts.errors import VttsError

    def fake_track(frames, **kw):
        next(iter(frames))
        raise VttsError("the face left the image")

    monkeypatch.setattr(track, "track", fake_track)
    out = tmp_path / "est.fap"
    argv = ["analyze", str(five_frames), "--model", HEAD, "-o", str(out), "--fbs"]
    argv += ["--report", str(tmp_path / "report")]
    r = in_process.vtts(*argv)
    assert r.returncode == 1 and "error: the face left the image" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"]


@pytest.mark.parametrize(
    "video, name",
    [("talk.mp4", "talk"), ("my talk.mp4", "my_talk"), ("#1.mp4", "1"), ("frames/", "frames")],
)
def test_stream_name(video, name):
    from vtts.api.analyze import stream_name as _stream_name

    assert _stream_name(video) == name
