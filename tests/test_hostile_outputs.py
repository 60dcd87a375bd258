"""Outputs never destroy inputs, links or devices, and SIGTERM cleans up as Ctrl-C (issue 21)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from .hostile import wav as hostile_wav

# in this process: what a command refuses, writes and leaves alone is the command's, not its
# process's; the process's own part, a signal, is test_sigterm_cleans_up_like_ctrl_c's
from .in_process import adi as adi_cli
from .in_process import vtts as vtts_cli

DATA = Path(__file__).parent / "data"
VTTS = Path(sys.executable).with_name("vtts")
MODELS = Path(__file__).parents[1] / "models"


@pytest.fixture
def model(tmp_path) -> Path:
    """A copy of cybatt (scene, tables, texture) in tmp_path."""
    for suffix in (".wrl", ".adt"):
        shutil.copy(MODELS / f"cybatt{suffix}", tmp_path / f"cybatt{suffix}")
    shutil.copy(MODELS / "cybatt-face.png", tmp_path / "cybatt-face.png")
    return tmp_path / "cybatt.wrl"


def unchanged(path: Path, before: bytes) -> bool:
    return path.read_bytes() == before


@pytest.mark.parametrize(
    "make_args, victim",
    [
        (lambda m: ["render", "--model", str(m), "-o", str(m.with_name("cybatt-face.png"))],
         "cybatt-face.png"),
        (lambda m: ["pose", "--model", str(m), "--fap", "3=100", "-o", str(m)], "cybatt.wrl"),
        (lambda m: ["pose", "--model", str(m), "-o", str(m.with_suffix(".adt"))], "cybatt.adt"),
    ],
)  # fmt: skip
def test_an_output_that_is_an_input_is_refused(model, make_args, victim):
    path = model.parent / victim
    before = path.read_bytes()
    r = vtts_cli(*make_args(model))
    assert r.returncode == 1, r.stdout
    assert "also an input" in r.stderr and "Traceback" not in r.stderr
    assert unchanged(path, before)


def test_encode_onto_its_input_is_refused(tmp_path):
    fap = tmp_path / "joy.fap"
    shutil.copy(DATA / "fap" / "xface-joy.fap", fap)
    before = fap.read_bytes()
    r = vtts_cli("encode", str(fap), "-o", str(fap))
    assert r.returncode == 1 and "also an input" in r.stderr
    assert unchanged(fap, before)


def test_analyze_onto_its_video_is_refused(tmp_path):
    video = tmp_path / "v.mp4"
    video.write_bytes(b"not really a video")
    r = vtts_cli("analyze", str(video), "--model", "cybatt", "-o", str(video))
    assert r.returncode == 1 and "also an input" in r.stderr
    assert video.read_bytes() == b"not really a video"


def test_two_outputs_naming_one_file_are_refused(tmp_path):
    out = tmp_path / "x"
    r = vtts_cli("say", "hi", "--model", "cybatt", "--fap-out", str(out), "--wav-out", str(out))
    assert r.returncode == 1 and "two outputs name the same file" in r.stderr
    assert not out.exists()


def test_an_output_link_or_device_is_refused(tmp_path):
    target = tmp_path / "precious.png"
    target.write_bytes(b"keep")
    link = tmp_path / "out.png"
    link.symlink_to(target)
    r = vtts_cli("render", "--model", "cybatt", "-o", str(link))
    assert r.returncode == 1 and "is a link" in r.stderr
    assert target.read_bytes() == b"keep" and link.is_symlink()
    r = vtts_cli("render", "--model", "cybatt", "-o", os.devnull)
    assert r.returncode == 1 and "not a regular file" in r.stderr


def test_a_failing_say_leaves_its_other_outputs_alone(tmp_path):
    fap, wav = tmp_path / "s.fap", tmp_path / "s.wav"
    fap.write_text("old fap")
    wav.write_text("old wav")
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "keep.txt").write_text("not a frame")  # the frames cannot go there: the say fails
    r = vtts_cli("say", "hello", "--model", "cybatt", "--fap-out", str(fap), "--wav-out", str(wav),
                 "--png-dir", str(frames), "--quiet")  # fmt: skip
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert fap.read_text() == "old fap" and wav.read_text() == "old wav"


def test_sigterm_cleans_up_like_ctrl_c(tmp_path):
    text = "This is a long sentence that takes a while to say and longer to render. " * 6
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen(
        [str(VTTS), "say", text, "--model", "cybatt", "-o", str(out / "talk.mp4"), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not list(out.glob(".*part*")):
        time.sleep(0.05)  # wait until the video is being written
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert list(out.iterdir()) == []
    assert not list(tmp_path.glob("vtts-say-*"))


def test_adi_build_never_rewrites_its_neutral_model(tmp_path):
    neutral = tmp_path / "n.wrl"
    shutil.copy(DATA / "models" / "head.wrl", neutral)
    before = neutral.read_bytes()
    r = adi_cli("build", str(neutral), str(neutral), "-o", str(neutral), "--embed")
    assert r.returncode == 1 and "also an input" in r.stderr
    assert neutral.read_bytes() == before


# ---- issue 45: every file a command writes, reports and "-" included -----------------------


@pytest.mark.parametrize("name", ["frames.csv", "psnr.png", "faps.png", "side-by-side.mp4"])
def test_analyze_report_never_replaces_its_video(tmp_path, name):
    report = tmp_path / "rep"
    report.mkdir()
    video = report / name
    video.write_bytes(b"the user's video")
    r = vtts_cli("analyze", str(video), "-o", str(tmp_path / "x.fap"), "--report", str(report))
    assert r.returncode == 1 and "also an input" in r.stderr and str(video) in r.stderr
    assert "Traceback" not in r.stderr
    assert video.read_bytes() == b"the user's video"
    assert {p.name for p in tmp_path.rglob("*")} == {name, "rep"}


def test_analyze_report_files_are_checked_with_the_outputs(tmp_path):
    video = tmp_path / "v.mp4"
    video.write_bytes(b"not really a video")
    report = tmp_path / "rep"
    report.mkdir()
    (report / "psnr.png").symlink_to(video)
    r = vtts_cli("analyze", str(video), "-o", str(tmp_path / "x.fap"), "--report", str(report))
    assert r.returncode == 1 and "is a link" in r.stderr
    r = vtts_cli("analyze", str(video), "-o", str(report / "frames.csv"), "--report", str(report))
    assert r.returncode == 1 and "two outputs name the same file" in r.stderr
    assert video.read_bytes() == b"not really a video" and not (report / "frames.csv").exists()


def test_analyze_with_a_model_never_replaces_the_models_files(model):
    from vtts.api.analyze import AnalyzeOptions, analyze
    from vtts.errors import VttsError

    video = model.with_name("v.mp4")
    video.write_bytes(b"not really a video")
    adt = model.with_suffix(".adt")
    before = adt.read_bytes()
    options = AnalyzeOptions(video=str(video), model=[str(model)], output=str(adt))
    with pytest.raises(VttsError, match="also an input"):
        analyze(options)
    assert adt.read_bytes() == before


@pytest.mark.parametrize(
    "args, bad",
    [
        (["-o", "pf/x.fap"], "pf/x-model-face.png"),  # the fitted head's texture
        (["-o", "x.fap", "--model-out", "pf/head.wrl"], "pf/head-face.png"),
        (["-o", "x.fap", "--report", "pf"], "pf/psnr.png"),
        (["-o", "pf/x.fap", "--model", "cybatt", "--report", "pf/.."], None),  # beside: fine
    ],
)
def test_analyze_writes_no_png_among_its_frames(tmp_path, args, bad):
    from PIL import Image

    frames = tmp_path / "pf"
    frames.mkdir()
    for i in range(2):
        Image.new("RGB", (32, 24)).save(frames / f"f{i}.png")
    before = sorted(p.name for p in frames.iterdir())
    r = vtts_cli("analyze", "pf", *args, cwd=tmp_path)
    assert "Traceback" not in r.stderr
    if bad is None:  # not refused for where it writes: it goes on to look for a face
        assert "among the frames" not in r.stderr
        return
    assert r.returncode == 1 and "among the frames of pf" in r.stderr and bad in r.stderr
    assert sorted(p.name for p in frames.iterdir()) == before


@pytest.mark.parametrize("name", ["landmarks.png", "overlay.png", "turned.png", "figures.json"])
def test_adi_fit_report_never_replaces_its_photo(tmp_path, name):
    shots = tmp_path / "shots"
    shots.mkdir()
    photo = shots / name
    photo.write_bytes(b"the user's photo")
    r = adi_cli("fit", str(photo), "-o", str(tmp_path / "me.wrl"), "--report", str(shots))
    assert r.returncode == 1 and "over its photo; choose another --report" in r.stderr
    assert photo.read_bytes() == b"the user's photo"
    assert {p.name for p in tmp_path.rglob("*")} == {name, "shots"}


def test_adi_fit_report_files_are_plain_files(tmp_path):
    photo = tmp_path / "me.png"
    photo.write_bytes(b"the user's photo")
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "overlay.png").symlink_to(photo)
    r = adi_cli(
        "fit", str(photo), "-o", str(tmp_path / "me.wrl"), "--report", str(tmp_path / "rep")
    )
    assert r.returncode == 1 and "over its photo" in r.stderr  # the link leads to the photo
    (tmp_path / "rep" / "overlay.png").unlink()
    (tmp_path / "rep" / "overlay.png").symlink_to(tmp_path / "elsewhere.png")
    r = adi_cli(
        "fit", str(photo), "-o", str(tmp_path / "me.wrl"), "--report", str(tmp_path / "rep")
    )
    assert r.returncode == 1 and "is a link" in r.stderr
    assert not (tmp_path / "elsewhere.png").exists() and not (tmp_path / "me.wrl").exists()


JOY = DATA / "fap" / "xface-joy.fap"
DASH = [
    ["analyze", "v.mp4", "-o", "-"],
    ["analyze", "v.mp4", "-o", "x.fap", "--report", "-"],
    ["analyze", "v.mp4", "-o", "x.fap", "--model-out", "-"],
    ["say", "hi", "--model", "cybatt", "-o", "-"],
    ["say", "hi", "--model", "cybatt", "--fap-out", "-"],
    ["say", "hi", "--model", "cybatt", "--wav-out", "-"],
    ["say", "hi", "--model", "cybatt", "--timings-out", "-"],
    ["say", "hi", "--model", "cybatt", "--curves-out", "-"],
    ["say", "hi", "--model", "cybatt", "--png-dir", "-"],
    ["say", "hi", "--model", "cybatt", "--web", "-"],
    ["play", str(JOY), "--model", "cybatt", "-o", "-"],
    ["play", str(JOY), "--model", "cybatt", "--curves-out", "-"],
    ["play", str(JOY), "--model", "cybatt", "--png-dir", "-"],
    ["render", "--model", "cybatt", "-o", "-"],
    ["pose", "--model", "cybatt", "-o", "-"],
    ["encode", str(JOY), "-o", "-"],
    ["decode", "x.fbs", "-o", "-"],
    ["batch", "jobs.jsonl", "--out", "-"],
]


@pytest.mark.parametrize("args", DASH, ids=[" ".join(a[:1] + a[-2:]) for a in DASH])
def test_dash_where_no_stdout_is_written_is_refused(tmp_path, args):
    (tmp_path / "v.mp4").write_bytes(b"not really a video")
    (tmp_path / "x.fbs").write_bytes(b"not really a stream")
    (tmp_path / "jobs.jsonl").write_text('{"render": true, "model": "cybatt", "output": "a.png"}\n')
    r = vtts_cli(*args, cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    assert "'-' would be one named '-'" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "-").exists()


def test_adi_fit_report_dash_is_refused(tmp_path):
    r = adi_cli("fit", "p.png", "-o", "me.wrl", "--report", "-", cwd=tmp_path)
    assert r.returncode == 1 and "'-' would be one named '-'" in r.stderr
    assert not (tmp_path / "-").exists()


def test_the_library_refuses_dash_too(tmp_path):
    from vtts.api.analyze import AnalyzeOptions
    from vtts.api.say import SayOptions, say
    from vtts.errors import VttsError

    with pytest.raises(VttsError, match="would be one named"):
        AnalyzeOptions(video=str(tmp_path / "v.mp4"), output="-")
    with pytest.raises(VttsError, match="--timings-out -"):
        say(SayOptions(text="hi", model=["cybatt"], timings_out="-", wav_out=str(tmp_path / "a")))
    assert list(tmp_path.iterdir()) == []


# ---- vtts batch: outputs stay in --out, and no two jobs write one file ------------------------


def test_a_batch_output_through_a_link_out_of_the_folder_is_refused(tmp_path):
    from vtts.batch.jobs import JobError, parse_job

    out, elsewhere = tmp_path / "clips", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "link").symlink_to(elsewhere)
    (out / "loop").symlink_to(out / "loop")
    job = {"render": True, "model": "cybatt", "output": "link/x.png"}
    with pytest.raises(JobError, match="'output': 'link/x.png' leads out of the batch's folder"):
        parse_job(job, out)
    with pytest.raises(JobError, match="'web': 'link' leads out"):
        parse_job({"say": "hi", "model": "cybatt", "web": "link"}, out)
    with pytest.raises(JobError, match="'png_dir': 'loop/f'"):
        parse_job({"say": "hi", "model": "cybatt", "png_dir": "loop/f"}, out)
    # a link inside the folder to a place inside it is the folder still, and so is --out a link
    (out / "sub").mkdir()
    (out / "inner").symlink_to(out / "sub")
    assert parse_job({**job, "output": "inner/x.png"}, out).outputs == ("inner/x.png",)
    (tmp_path / "out-link").symlink_to(out)
    assert parse_job({**job, "output": "sub/x.png"}, tmp_path / "out-link").outputs


def test_a_batch_refuses_a_link_made_after_the_jobs_were_read(tmp_path):
    from vtts.batch.jobs import parse_job
    from vtts.batch.worker import JobRunner

    out, elsewhere = tmp_path / "clips", tmp_path / "elsewhere"
    (out / "sub").mkdir(parents=True)
    elsewhere.mkdir()
    job = parse_job({"render": True, "model": "cybatt", "output": "sub/x.png"}, out)
    (out / "sub").rmdir()
    (out / "sub").symlink_to(elsewhere)
    result = JobRunner().run(job, str(out))
    assert not result.ok and not result.internal and "leads out of" in result.message
    assert list(elsewhere.iterdir()) == []


@pytest.mark.parametrize(
    "first, second, shared",
    [
        ({"web": "w"}, {"output": "w/talk.glb"}, "w/talk.glb"),  # the issue's
        ({"fap_out": "w/index.html"}, {"web": "w"}, "w"),
        ({"png_dir": "f"}, {"wav_out": "f/0001.png"}, "f/0001.png"),
        ({"web": "w"}, {"png_dir": "w/vendor"}, "w/vendor"),
        ({"output": "a.mp4"}, {"fap_out": "a.mp4/x.fap"}, "a.mp4/x.fap"),
        ({"web": "w"}, {"web": "./w/"}, "w"),
    ],
)
def test_batch_jobs_whose_outputs_overlap_clash(tmp_path, first, second, shared):
    from vtts.batch.jobs import as_jobs

    base = {"say": "hi", "model": "cybatt"}
    checked = as_jobs([{**base, "id": "a", **first}, {**base, "id": "b", **second}], tmp_path)
    assert [j.id for j in checked.jobs] == ["a"]
    assert [e.message for e in checked.errors] == [f"'{shared}' is also written by line 1"]
    if first.keys() & second.keys():
        return  # one job cannot give an option twice
    # and within one job
    checked = as_jobs([{**base, **first, **second}], tmp_path)
    assert not checked.jobs
    assert checked.errors[0].message == f"'{shared}' is also written by this job's other output"


def test_batch_outputs_side_by_side_do_not_clash(tmp_path):
    from vtts.batch.jobs import as_jobs

    base = {"say": "hi", "model": "cybatt"}
    jobs = [{**base, "web": "w"}, {**base, "web": "w2"}, {**base, "output": "w.mp4"},
            {**base, "png_dir": "f/a"}, {**base, "png_dir": "f/b"}]  # fmt: skip
    checked = as_jobs(jobs, tmp_path)
    assert not checked.errors and len(checked.jobs) == 5


# ---- the web folder: written into ".", and only ever replacing what vtts wrote ----------------


def tree(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()
    }


def test_web_into_the_current_folder(tmp_path):
    here = tmp_path / "here"
    here.mkdir()
    inode = here.stat().st_ino
    for _ in range(2):  # new, then rewritten
        r = vtts_cli("play", str(JOY), "--model", "cybatt", "--web", ".", "--quiet", cwd=here)
        assert r.returncode == 0, r.stderr
        assert (here / "index.html").is_file() and (here / "vendor").is_dir()
        assert not [p for p in here.iterdir() if p.name.startswith(".vtts-web")]
        assert sorted(p.name for p in tmp_path.iterdir()) == ["here"]  # no ..XXXX.old beside
    assert here.stat().st_ino == inode  # the shell's folder is the same folder


def test_png_frames_into_the_current_folder(tmp_path):
    here = tmp_path / "here"
    here.mkdir()
    inode = here.stat().st_ino
    args = ("play", str(JOY), "--model", "cybatt", "--size", "32x24", "--png-dir", ".")
    r = vtts_cli(*args, "--quiet", cwd=here)
    assert r.returncode == 0, r.stderr
    names = sorted(p.name for p in here.iterdir())
    assert names[0] == "frame_000000.png" and all(n.startswith("frame_") for n in names)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here"]
    assert here.stat().st_ino == inode
    r = vtts_cli(*args, cwd=here)  # not empty now: refused as before
    assert r.returncode == 1 and "not empty" in r.stderr


@pytest.mark.parametrize(
    "add",
    [
        lambda w: (w / "vendor" / "mine.js").write_text("mine"),
        lambda w: (w / "vendor" / "addons" / "loaders" / "mine.js").write_text("mine"),
        lambda w: (w / ".htaccess").write_text("mine"),
        lambda w: (w / "vendor" / "extra").mkdir(),
        lambda w: (w / "vendor" / "link").symlink_to(w.parent),
        lambda w: (w / "vendor" / "VERSION").unlink() or (w / "vendor" / "VERSION").mkdir(),
    ],
    ids=["vendor file", "deep file", "hidden file", "empty folder", "link", "folder for a file"],
)
def test_web_rewrite_never_deletes_what_the_user_added(tmp_path, add):
    from vtts.export.web import WebError, write_web
    from vtts.face import load_model
    from vtts.face.miap import N_PARAMS

    head = load_model(DATA / "models" / "head.wrl")
    w = write_web(tmp_path / "w", [head], [np.zeros((3, N_PARAMS))], 30.0)
    add(w)
    before = tree(w), sorted(p.relative_to(w).as_posix() for p in w.rglob("*"))
    with pytest.raises(WebError, match="also holds files vtts did not write"):
        write_web(w, [head], [np.zeros((5, N_PARAMS))], 30.0)
    assert (tree(w), sorted(p.relative_to(w).as_posix() for p in w.rglob("*"))) == before
    r = vtts_cli("play", str(JOY), "--model", "cybatt", "--web", str(w))
    assert r.returncode == 1 and "did not write" in r.stderr and "Traceback" not in r.stderr


def test_web_rewrite_replaces_its_own_files_and_recovers_from_a_killed_write(tmp_path):
    from vtts.export.web import FILES_NAME, write_web
    from vtts.face import load_model
    from vtts.face.miap import N_PARAMS

    head = load_model(DATA / "models" / "head.wrl")
    w = write_web(tmp_path / "w", [head], [np.zeros((3, N_PARAMS))], 30.0)
    listed = set((w / FILES_NAME).read_text().split())
    assert listed == set(tree(w)) and "vendor/three.module.min.js" in listed
    (w / ".vtts-web.abc.part" / "vendor").mkdir(parents=True)  # a write killed midway
    (w / FILES_NAME).unlink()  # as vtts wrote it before it kept the list
    write_web(w, [head], [np.zeros((7, N_PARAMS))], 30.0)
    assert set(tree(w)) == listed and not list(w.glob(".vtts-web.*"))


def test_a_failed_web_rewrite_leaves_the_previous_folder(tmp_path, monkeypatch):
    from vtts.export import web
    from vtts.face import load_model
    from vtts.face.miap import N_PARAMS

    head = load_model(DATA / "models" / "head.wrl")
    w = web.write_web(tmp_path / "w", [head], [np.zeros((3, N_PARAMS))], 30.0)
    before = tree(w)
    moves = []

    def fail_on_the_third(src, dst):  # the index and an entry moved aside, then a failure
        moves.append(src)
        if len(moves) == 3:
            raise OSError(28, "No space left on device", str(dst))
        os.replace(src, dst)

    monkeypatch.setattr(web.os, "replace", fail_on_the_third)
    with pytest.raises(OSError):
        web.write_web(w, [head], [np.zeros((9, N_PARAMS))], 30.0)
    monkeypatch.undo()
    assert tree(w) == before and not list(w.glob(".vtts-web.*"))
    with pytest.raises(OSError):  # and a new folder that fails is not left behind
        monkeypatch.setattr(web, "encode_aac", lambda *a: (_ for _ in ()).throw(OSError("no")))
        web.write_web(tmp_path / "new", [head], [np.zeros((3, N_PARAMS))], 30.0,
                      audio=hostile_wav(tmp_path / "a.wav"))  # fmt: skip
    assert not (tmp_path / "new").exists()


# ---- adi import: what is written loads back, or nothing is replaced ---------------------------


def textured_avatar(path: Path, scale: tuple[float, float]) -> Path:
    """A grid avatar with one target and a texture under a KHR_texture_transform ``scale``."""
    import io

    import pygltflib as gl
    from PIL import Image

    from .avatar.avatar_helpers import USHORT, Builder, grid, moves

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 10, 10)).save(buf, format="PNG")
    pos, faces = grid()
    b = Builder()
    uv = b.accessor(pos[:, :2] + 0.5)
    b.doc.images.append(gl.Image(bufferView=b.view(buf.getvalue()), mimeType="image/png"))
    b.doc.textures.append(gl.Texture(source=0))
    info = gl.TextureInfo(index=0, extensions={"KHR_texture_transform": {"scale": list(scale)}})
    b.doc.materials.append(
        gl.Material(pbrMetallicRoughness=gl.PbrMetallicRoughness(baseColorTexture=info))
    )
    b.doc.extensionsUsed = ["KHR_texture_transform"]
    targets = [{"POSITION": b.accessor(moves(len(pos), 1))}]
    attributes = {"POSITION": b.accessor(pos), "TEXCOORD_0": uv}
    indices = b.accessor(faces.reshape(-1), USHORT)
    b.node(name="Head", mesh=b.mesh(attributes, indices, targets, ["jawOpen"], material=0))
    return b.save(path)


@pytest.mark.parametrize("scale", [(1e308, 1.0), (1.0, -1e308), (1e308, 1e308)])
def test_adi_import_of_an_overflowing_model_keeps_the_previous_one(tmp_path, scale):
    avatar = textured_avatar(tmp_path / "a.glb", scale)
    previous = {tmp_path / n: n.encode() for n in ("me.wrl", "me.adt", "me-tex0.png")}
    for path, data in previous.items():
        path.write_bytes(data)
    r = adi_cli("import", str(avatar), "-o", str(tmp_path / "me.wrl"))
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "would not load back, so nothing was written" in r.stderr
    assert "TextureCoordinate point holds a number that is not finite" in r.stderr
    assert all(path.read_bytes() == data for path, data in previous.items())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.glb", "me-tex0.png", "me.adt",
                                                         "me.wrl"]  # fmt: skip


def test_adi_import_of_a_large_but_finite_scale_loads(tmp_path):
    avatar = textured_avatar(tmp_path / "a.glb", (1e200, 1.0))
    r = adi_cli("import", str(avatar), "-o", str(tmp_path / "me.wrl"))
    assert r.returncode == 0, r.stderr


def test_imported_tables_that_are_not_finite_are_not_written(tmp_path):
    from vtts.avatar.importer import import_avatar
    from vtts.errors import AvatarError

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no feature points: no FAPUs of its own
        avatar = import_avatar(textured_avatar(tmp_path / "a.glb", (1.0, 1.0)))
    adt = next(a for a in avatar.tables.adts.values() if a.meshes)
    adt.meshes[0].displacements[0, 0, 1] = np.nan
    with pytest.raises(AvatarError, match="a number of its displacements is not finite"):
        avatar.write(tmp_path / "me.wrl")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.glb"]


@pytest.mark.parametrize(
    "args, words",
    [
        (["--web", "w", "-o", "w/x.mp4"], "w/x.mp4: error: this output lies inside w"),
        (["--web", "w", "--curves-out", "w/vendor/c.json"], "this output lies inside w"),
        (["--web", "w", "--audio", "w/speech.m4a"], "w/speech.m4a: error: this input lies inside"),
        (["--web", "w", "--png-dir", "w"], "two outputs name the same folder"),
        (["--web", "w", "--png-dir", "w/f"], "the output folders w and w/f overlap"),
        (["--png-dir", "f", "--web", "f/w"], "the output folders f and f/w overlap"),
        (["--png-dir", "f", "-o", "f/x.mp4"], "this output lies inside f"),
    ],
)
def test_a_folder_a_command_fills_holds_none_of_its_other_files(tmp_path, args, words):
    if "w/speech.m4a" in args:  # a previous web folder, whose audio is given
        assert vtts_cli("play", str(JOY), "--model", "cybatt", "--audio",
                        str(hostile_wav(tmp_path / "a.wav")), "--web", "w", cwd=tmp_path
                        ).returncode == 0  # fmt: skip
        (tmp_path / "a.wav").unlink()
    before = tree(tmp_path)
    r = vtts_cli("play", str(JOY), "--model", "cybatt", "--size", "32x24", *args, cwd=tmp_path)
    assert r.returncode == 1 and words in r.stderr and "Traceback" not in r.stderr
    assert tree(tmp_path) == before
