"""Live streaming end to end: raw frames → vtts analyze - --stream → vtts play -, over OS pipes;
and each way a stream can go wrong (garbage, truncation, wrong size, a reader that leaves,
Ctrl-C)."""

from __future__ import annotations

import dataclasses
import io
import os
import signal
import subprocess
import sys
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest

from vtts.analysis.video import read_pipe
from vtts.api.analyze import QUANTIZER
from vtts.errors import AnalysisError
from vtts.fap import FapStream
from vtts.fap.coding import (
    PAPER_17,
    StreamEncoder,
    decode,
    encode,
    frame_of,
    paired_predictors,
    read_header,
)
from vtts.render import probe_media

from .. import in_process
from ..signals import signal_other_threads, wait_idle

DATA = Path(__file__).parents[1] / "data"
CLIP = DATA / "video" / "carphone_qcif.mp4"
HEAD = DATA / "models" / "head.wrl"
EXE = Path(sys.executable).with_name("vtts")
FRAMES = 4  # the accurate analysis runs about 2 QCIF frames/s on the 2-core machine


def vtts(*args: str, stdin: bytes = b"") -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(EXE), *args], input=stdin, capture_output=True, timeout=300, check=False
    )


def vtts_here(*args: str, stdin: bytes = b"") -> subprocess.CompletedProcess:
    """``vtts ARGS`` in this process (``stdin`` through an OS pipe), as :func:`vtts` returns a
    process's: stdout and stderr in bytes."""
    return in_process.vtts(*args, stdin=stdin, text=False)


def synthetic(n: int = 6) -> FapStream:
    rng = np.random.default_rng(1)
    values = np.zeros((n, 68))
    mask = np.zeros((n, 68), dtype=bool)
    for k in PAPER_17:
        values[:, k - 1] = np.round(np.cumsum(rng.normal(0, 40, n)))
        mask[:, k - 1] = True
    t = np.cumsum(rng.normal(0, 5, (n, 3)), axis=0)
    return FapStream(25.0, "synthetic", values, mask, translation=t)


def streamed(s: FapStream) -> list[bytes]:
    enc = StreamEncoder(
        fps=s.fps,
        faps=PAPER_17,
        translation=True,
        constant_mask=True,
        predictors=paired_predictors(PAPER_17),
    )
    return [enc.header(), *(enc.frames(frame_of(s, i)) for i in range(s.n_frames)), enc.end()]


def pngs(folder: Path) -> list[bytes]:
    from PIL import Image

    return [np.asarray(Image.open(p)).tobytes() for p in sorted(folder.glob("*.png"))]


def decoded_frames() -> list[str]:
    """The ffmpeg command that decodes the first :data:`FRAMES` frames of Carphone to raw
    ``rgb24`` on stdout, with the wheel's ffmpeg."""
    return [imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(CLIP), "-frames:v",
            str(FRAMES), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"]  # fmt: skip


def live(folder: Path, analyze: list[str], model: str, cwd: str | None = None) -> Path:
    """ffmpeg | vtts analyze - --size 176x144 --stream ANALYZE --quiet | tee live.fbs | vtts play
    - --model MODEL --size 176x144 -o live.mp4 --png-dir live/, three processes over OS pipes,
    writing into ``folder`` (the analysis runs in the folder ``cwd``): the saved stream (each
    command ended with status 0)."""
    saved, out = folder / "live.fbs", folder / "live.mp4"
    decoder = subprocess.Popen(decoded_frames(), stdout=subprocess.PIPE)
    analysis = subprocess.Popen(
        [str(EXE), "analyze", "-", "--size", "176x144", "--stream", *analyze, "--quiet"],
        stdin=decoder.stdout, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=cwd)  # fmt: skip
    decoder.stdout.close()
    play = subprocess.Popen(
        [str(EXE), "play", "-", "--model", model, "--size", "176x144", "-o", str(out),
         "--png-dir", str(folder / "live"), "--quiet"],
        stdin=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    with open(saved, "wb") as keep:  # tee: the stream as it went by
        while chunk := analysis.stdout.read1(1 << 16):
            keep.write(chunk)
            play.stdin.write(chunk)
            play.stdin.flush()
    play.stdin.close()
    assert decoder.wait(60) == 0
    assert analysis.wait(300) == 0, analysis.stderr.read().decode()
    assert play.wait(300) == 0, play.stderr.read().decode()
    assert decode(saved.read_bytes()).n_frames == FRAMES
    assert probe_media(out).frames == FRAMES
    return saved


def face_steps(saved: Path) -> dict:
    """The base steps in the header of the stream ``saved`` (``encode``'s ``steps``), checked
    to be measured on the face (--steps face), not MPEG-4's."""
    from vtts.fap.table import FAPS

    h = read_header(saved.read_bytes())
    assert h.base_steps != tuple(FAPS[k - 1].quant_step for k in h.low), h.base_steps
    return {**dict(zip(h.low, h.base_steps, strict=True)),
            **dict(zip(("tx", "ty", "tz"), h.translation_base_steps, strict=False))}  # fmt: skip


def test_webcam_pipeline_with_a_file(tmp_path):
    """ffmpeg | vtts analyze - --stream | tee | vtts play -: the documented pipeline, for real,
    with the head fitted to the first face."""
    head = tmp_path / "head.wrl"
    saved = live(tmp_path, ["--model-out", str(head)], str(head))
    face_steps(saved)  # measured on the fitted head at the first estimate
    # the stream as a file, played in this process: the same frames
    r = vtts_here("play", str(saved), "--model", str(head), "--size", "176x144", "--fps", "25",
                  "--png-dir", str(tmp_path / "file"), "--quiet")  # fmt: skip
    assert r.returncode == 0, r.stderr.decode()
    live_frames, whole = pngs(tmp_path / "live"), pngs(tmp_path / "file")
    assert len(live_frames) == FRAMES and live_frames == whole


def test_webcam_pipeline_with_a_given_model(tmp_path):
    """The same pipeline with a bundled head (issue 40; a traceback once): nothing is fitted or
    written, no --model-out; the stream carries what a file analysis of the same frames with
    that model estimates (placed on the first face's landmarks), coded with the steps measured
    at the first estimate."""
    from PIL import Image

    from vtts.api.analyze import AnalyzeOptions, analyze

    # in a folder nothing can be written in: a given model needs no folder for a fitted head
    saved = live(tmp_path, ["--model", "cybatt"], "cybatt", cwd="/proc")
    steps = face_steps(saved)
    frames = tmp_path / "frames"  # the same frames as a PNG folder, analyzed in this process
    frames.mkdir()
    raw = subprocess.run(decoded_frames(), capture_output=True, check=True).stdout
    for i, frame in enumerate(np.frombuffer(raw, np.uint8).reshape(FRAMES, 144, 176, 3)):
        Image.fromarray(frame).save(frames / f"f{i}.png")
    found = analyze(AnalyzeOptions(video=str(frames), model=["cybatt"], track=True,
                                   output=str(tmp_path / "file.fap")))  # fmt: skip
    assert found.tracked.first == 0 and not found.fitted
    # the stream's quantizer is the command's default, as a file's
    header = read_header(saved.read_bytes())
    assert header.quantizer == QUANTIZER
    coded = encode(found.stream, steps=steps, quantizer=header.quantizer)
    got, want = decode(saved.read_bytes()), decode(coded)
    assert np.array_equal(got.values, want.values) and np.array_equal(got.mask, want.mask)
    assert np.array_equal(got.translation, want.translation)


def test_read_pipe_yields_frames_and_names_a_partial_one():
    frame = np.arange(32 * 16 * 3, dtype=np.uint8).reshape(16, 32, 3)
    video = read_pipe(io.BytesIO(frame.tobytes() * 2 + b"x" * 100), (32, 16), name="-")
    assert video.fps == 25.0 and video.n_frames is None and video.kind == "pipe"
    got = []
    with pytest.raises(AnalysisError, match="byte 3072: the pipe ends inside frame 2 .100 of"):
        for f in video.frames():
            got.append(f)
    assert len(got) == 2 and np.array_equal(got[1], frame)
    with pytest.raises(AnalysisError, match="read once"):
        next(video.frames())
    with pytest.raises(AnalysisError, match="too small"):
        read_pipe(io.BytesIO(b""), (8, 8))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["-o", "x.fap"], "give --size"),
        (["--size", "176x144", "--report", "rep", "-o", "x.fap"], "pipe cannot"),
        (["--size", "176x144", "--stream", "-o", "x.fbs"], "give no -o"),
        (["--size", "176x144", "--stream"], "--model-out"),
        (
            ["--size", "176x144", "--stream", "--model", "cybatt", "--model-out", "x.wrl"],
            "with --model cybatt nothing is fitted",
        ),
        # a TypeError traceback once (issue 45): the model is read, then the pipe
        (["--size", "176x144", "--stream", "--model", str(HEAD)], "the pipe ends inside"),
        (["--size", "176x144", "--stream", "--model=--"], "no model '--'"),
        (["--size", "176x144"], "nothing to write"),
        (["--size", "4x4", "-o", "x.fap"], "too small"),
        (["--size", "5000x5000", "-o", "x.fap"], "limit"),
        (["--size", "176x144", "-o", "x.fap"], "byte 0: the pipe ends inside frame 0"),
        (["--size", "176x144", "--texture", "mean", "-o", "x.fap"], "needs the whole video"),
    ],
)
def test_analyze_stdin_errors(tmp_path, args, message):
    """The errors of the frames' bytes run the command as a process; the others run it in this
    process, from the same bytes through a pipe."""
    args = [str(tmp_path / a) if a.startswith(("x.", "rep")) else a for a in args]
    stdin = b"garbage, not frames"
    if "the pipe ends inside" in message:
        r = vtts("analyze", "-", *args, stdin=stdin)
    else:
        r = vtts_here("analyze", "-", *args, stdin=stdin)
    err = r.stderr.decode()
    assert r.returncode == 1 and message in err and "Traceback" not in err, err
    assert r.stdout == b""


def test_size_is_for_a_pipe():
    r = vtts_here("analyze", str(CLIP), "--size", "176x144", "-o", "x.fap")
    assert r.returncode == 1 and b"--size is the size of raw frames" in r.stderr


def test_play_stdin_renders_each_frame_and_a_whole_fbs_too(tmp_path):
    """The streamed packets through a real process; the whole .fbs in this process."""
    s = synthetic(5)
    data = b"".join(streamed(s))
    r = vtts("play", "-", "--model", str(HEAD), "--size", "32x24", "-o", "-", stdin=data)
    assert r.returncode == 0, r.stderr.decode()
    assert len(r.stdout) == 5 * 32 * 24 * 3
    whole = vtts_here("play", "-", "--model", str(HEAD), "--size", "32x24", "-o", "-",
                      stdin=encode(s))  # fmt: skip
    assert whole.returncode == 0 and whole.stdout == r.stdout


@pytest.mark.parametrize(
    ("cut", "message"),
    [
        (lambda d, p: b"\x00garbage" * 20, "byte 0: not a vtts FAP bitstream"),
        (lambda d, p: b"", "truncated"),
        (lambda d, p: d[: len(p[0]) + len(p[1]) - 1], "inside the CRC of packet 0"),
        (lambda d, p: d[:-4], "inside the end marker's CRC"),
    ],
)
def test_play_stdin_bad_streams(tmp_path, cut, message):
    """The garbage ends a real process; the other cuts run the command in this process, through
    a pipe."""
    parts = streamed(synthetic(3))
    out = tmp_path / "o.mp4"
    args = ["play", "-", "--model", str(HEAD), "--size", "32x24", "-o", str(out)]
    data = cut(b"".join(parts), parts)
    if message.startswith("byte 0"):
        r = vtts(*args, stdin=data)
    else:
        r = vtts_here(*args, stdin=data)
    err = r.stderr.decode()
    assert r.returncode == 1 and message in err and "Traceback" not in err, err
    assert not out.exists()  # an MP4 is renamed into place only at the end of the stream


def test_play_stdin_rejects_another_rate_and_whole_stream_options():
    """In this process, the stream through a pipe."""
    data = b"".join(streamed(synthetic(2)))
    r = vtts_here("play", "-", "--model", str(HEAD), "--fps", "30", "-o", "-", stdin=data)
    assert r.returncode == 1 and b"its own rate, 25 Hz" in r.stderr
    r = vtts_here("play", "-", "--model", str(HEAD), "--web", "w", "-o", "-", stdin=data)
    assert r.returncode == 1 and b"need the whole stream" in r.stderr


def test_play_stdin_quiet_when_the_reader_leaves():
    """`vtts play - -o - | head -c 1`: the reader goes away; vtts ends without a traceback."""
    parts = streamed(synthetic(40))
    p = subprocess.Popen(
        [str(EXE), "play", "-", "--model", str(HEAD), "--size", "64x48", "-o", "-"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    p.stdin.write(b"".join(parts))
    p.stdin.close()
    assert p.stdout.read(1)
    p.stdout.close()
    assert p.wait(120) == 141
    assert b"Traceback" not in p.stderr.read()


def test_play_stdin_ctrl_c_waiting_for_a_packet():
    parts = streamed(synthetic(3))
    p = subprocess.Popen(
        [str(EXE), "play", "-", "--model", str(HEAD), "--size", "32x24", "-o", "-"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    p.stdin.write(parts[0] + parts[1])
    p.stdin.flush()
    assert len(p.stdout.read(32 * 24 * 3)) == 32 * 24 * 3  # frame 0 came: it waits for frame 1
    os.kill(p.pid, signal.SIGINT)
    assert p.wait(60) == 130
    err = p.stderr.read()
    assert b"interrupted" in err and b"Traceback" not in err
    p.stdin.close()


def live_player() -> subprocess.Popen:
    return subprocess.Popen(
        [str(EXE), "play", "-", "--model", str(HEAD), "--size", "32x24", "-o", "-"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip


def ends_interrupted(p: subprocess.Popen, within: float = 30) -> None:
    """``p`` ends within ``within`` seconds with 130 and "interrupted" (killed if it does not)."""
    try:
        code = p.wait(within)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()
        pytest.fail(f"still running {within:g} s after the signal")
    err = p.stderr.read()
    assert code == 130 and b"interrupted" in err and b"Traceback" not in err, (code, err)
    p.stdin.close()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_play_stdin_a_signal_another_thread_takes(sig):
    """The kernel may hand a signal sent to the process to any thread that does not block it:
    the one reading the next packet, a BLAS thread. One that does, while the main thread waits
    for the next frame's geometry, ends the command as one to the main thread does."""
    parts = streamed(synthetic(3))
    p = live_player()
    p.stdin.write(parts[0] + parts[1])
    p.stdin.flush()
    assert len(p.stdout.read(32 * 24 * 3)) == 32 * 24 * 3
    wait_idle(p.pid)  # every thread asleep: the main one waits for the packet's reader
    assert signal_other_threads(p.pid, sig) >= 1  # at least the reader of stdin
    ends_interrupted(p)


def test_play_stdin_a_signal_another_thread_takes_before_the_header():
    """The same while the main thread itself waits for the stream's header."""
    p = live_player()
    wait_idle(p.pid)
    if not signal_other_threads(p.pid, signal.SIGINT):
        p.kill()
        p.wait()
        pytest.skip("no thread but the main one yet (no BLAS threads on one core)")
    ends_interrupted(p)


def test_a_batch_job_does_not_play_stdin(tmp_path):
    from vtts.batch.jobs import JobError, parse_job

    with pytest.raises(JobError, match="stdin"):
        parse_job({"play": "-", "model": "cybatt", "output": "a.mp4"}, tmp_path)


@pytest.mark.parametrize("model", ["cybatt", str(HEAD)])  # with FAPUs, and without (no ES)
def test_estimate_stream_sends_what_a_whole_fbs_codes(model):
    """EstimateStream's packets decode to the stream ``vtts analyze -o OUT.fbs`` codes from the
    same estimates, a held frame setting no FAP; the head goes in place before the header."""
    from vtts.analysis.result import Analysis, FrameEstimate
    from vtts.analysis.streaming import EstimateStream
    from vtts.face import load_model
    from vtts.render.camera import Camera

    fapu = load_model(model).fapu
    unknowns = (48, 49, 50, "tx", "ty", "tz", 31, 32, 35, 36, 3, 4, 5, 6, 7, 12, 13)
    rng = np.random.default_rng(5)
    estimates = []
    for i in range(5):
        params = np.zeros(100)
        params[[u - 1 for u in unknowns if isinstance(u, int)]] = rng.normal(0, 200, 14)
        estimates.append(FrameEstimate(i, i / 25, params, translation=rng.normal(0, 3, 3)))
    # frame 3 held (the landmarks lost the face): its packet sets no FAP
    estimates[3] = dataclasses.replace(estimates[2], index=3, time=3 / 25, held=True)
    sink = io.BytesIO()
    order = []
    out = EstimateStream(sink, fps=25.0, unknowns=unknowns, name="clip", fapu=lambda: fapu,
                         before_header=lambda: order.append(sink.tell()))  # fmt: skip
    for fe in estimates:
        out(fe)
    out.end()
    assert order == [0]  # before anything was written
    whole = Analysis(estimates, unknowns, 25.0, Camera(1, 1, 0, 0)).stream("clip", fapu=fapu)
    got, want = decode(sink.getvalue()), decode(encode(whole))
    assert np.array_equal(got.values, want.values) and np.array_equal(got.mask, want.mask)
    assert not got.mask[3].any() and got.mask[[0, 1, 2, 4]][:, [47, 2]].all()
    assert (got.translation is None) == (fapu is None) == (want.translation is None)
    assert fapu is None or np.array_equal(got.translation, want.translation)
    assert out.frames == 5 and out.framing_s / 5 < 0.05
    # with base steps of its own, taken at the first estimate: what encode(steps=) codes
    steps = {3: 20, 4: 30, 12: 40, 13: 40, 31: 9, 32: 11, 48: 120, "tx": 2, "tz": 9}
    seen, plain = [], sink.getvalue()
    sink = io.BytesIO()
    out = EstimateStream(sink, fps=25.0, unknowns=unknowns, name="clip", fapu=lambda: fapu,
                         steps=lambda first: seen.append(first.index) or steps)  # fmt: skip
    for fe in estimates:
        out(fe)
    out.end()
    assert seen == [0]
    got, want = decode(sink.getvalue()), decode(encode(whole, steps=steps))
    assert np.array_equal(got.values, want.values) and np.array_equal(got.mask, want.mask)
    assert fapu is None or np.array_equal(got.translation, want.translation)
    assert len(sink.getvalue()) < len(plain)  # the lips' steps 15-20 times MPEG-4's: fewer bytes
