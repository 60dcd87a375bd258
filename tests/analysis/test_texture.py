"""The texture of a head made for a video: what the tracked frames show, their mean and the
robust least-squares texture (:mod:`vtts.analysis.texture`, ``vtts analyze --texture``)."""

from __future__ import annotations

import itertools
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vtts.analysis.quality import decoded_frames, sequence_psnr, stream_psnr
from vtts.analysis.texture import MIN_WEIGHT, mean_texture, retexture, robust_texture
from vtts.analysis.track import track
from vtts.analysis.video import read_video
from vtts.errors import AnalysisError
from vtts.face import load_model
from vtts.fit.frame import frame_texture

CARPHONE = Path(__file__).parents[1] / "data" / "video" / "carphone_qcif.mp4"
FPS = 29.97


def _frames(n: int) -> list[np.ndarray]:
    return list(itertools.islice(read_video(CARPHONE).frames(), n))


#: The frame the tracked head is fitted to: the one ``vtts analyze`` fits on frames 16–21 too
#: (its most typical), so that test_analyze_writes_… shares the fit.
ANCHOR = 18


@pytest.fixture(scope="module")
def tracked(tmp_path_factory, fits):
    """Carphone's first 40 frames, every second one, tracked with a head fitted to frame
    :data:`ANCHOR` (the man moves his head and mouth in them)."""
    folder = tmp_path_factory.mktemp("texture")
    frames = _frames(40)
    with fits.sharing():
        result = track(frames, fps=FPS, model_path=folder / "car.wrl", step=2, tracking=True,
                       anchor=ANCHOR)  # fmt: skip
    return result, frames, folder


def _copy(folder: Path, to: Path) -> Path:
    to.mkdir()
    for p in folder.iterdir():
        if p.name.startswith("car"):
            shutil.copy(p, to / p.name)
    return to / "car.wrl"


def test_the_mean_texture_brings_the_decoded_frames_closer(tracked, tmp_path):
    result, frames, folder = tracked
    wrl = _copy(folder, tmp_path / "head")
    model = load_model(str(wrl))
    stream = result.analysis.stream("car", fapu=model.fapu)
    before = stream_psnr(frames, stream, model, video_fps=FPS)
    png = wrl.with_name("car-frame.png")
    old = np.asarray(Image.open(png).convert("RGB"))
    assert np.array_equal(old, frame_texture(frames[ANCHOR]))  # the anchor's texture to start
    copied = replace(result, model=model, fitted=[wrl.with_name(p.name) for p in result.fitted])
    again = retexture(copied, frames, (176, 144))
    after = stream_psnr(frames, stream, again, video_fps=FPS)
    # the summed error over the frames falls: more than a dB on these 20 frames (about +1.7
    # dB on the whole sequence); the anchor frame itself, no longer its own texture, falls
    assert sequence_psnr(after) > sequence_psnr(before) + 1.0, (before, after)
    assert after[ANCHOR // 2] < before[ANCHOR // 2]
    new = np.asarray(Image.open(png).convert("RGB"))
    assert new.shape == old.shape
    # the canvas around the frame (nothing drawn there) keeps its texels
    assert np.array_equal(new[150:, :], old[150:, :]) and np.array_equal(new[:, 180:], old[:, 180:])
    assert not [p for p in png.parent.iterdir() if p.name.startswith(".")]  # no temporary left


@pytest.fixture(scope="module")
def redder(tracked, tmp_path_factory):
    """Frames rendered by the decoder with another texture (the anchor's, 40 levels redder), at
    the video frames the estimates are of (black between): ``(video, old texture, model)``."""
    result, frames, folder = tracked
    wrl = _copy(folder, tmp_path_factory.mktemp("red") / "red")
    png = wrl.with_name("car-frame.png")
    old = np.asarray(Image.open(png).convert("RGB"))
    red = old.astype(np.int16)
    red[..., 0] += 40
    Image.fromarray(np.clip(red, 0, 255).astype(np.uint8)).save(png)
    stream = result.analysis.stream("car", fapu=load_model(str(wrl)).fapu)
    shown = [rgba[..., :3] for rgba in decoded_frames(stream, load_model(str(wrl)), (176, 144))]
    # the decoder's frame i shows video frame 2i: give the texture those at their indices
    video = [np.zeros_like(frames[0]) for _ in frames]
    for i, image in enumerate(shown):
        video[2 * i] = image
    # (the estimates themselves, which the stream carries to within its quantization)
    return video, old, load_model(str(_copy(folder, tmp_path_factory.mktemp("plain") / "p")))


def _red_shift(new: np.ndarray, old: np.ndarray) -> np.ndarray:
    """The change of the texels that changed, ``(n, 3)`` levels."""
    changed = np.abs(new.astype(int) - old.astype(int)).max(axis=2) > 0
    assert changed.sum() > 3000  # the face, hair and neck the frames show
    return new.astype(int)[changed] - old.astype(int)[changed]


def test_a_texture_every_frame_shows_comes_back(tracked, redder):
    # the mean of what they show is that texture wherever the frames saw it well
    result, _, _ = tracked
    video, old, model = redder
    new = mean_texture(model, result.analysis.camera, (176, 144), result.analysis.frames, video,
                       old)  # fmt: skip
    diff = _red_shift(new, old)
    # the red shift comes back (texels along the outline and rarely seen ones only partly)
    assert np.median(diff[:, 0]) >= 36, np.median(diff[:, 0])
    assert abs(np.median(diff[:, 1])) <= 2 and abs(np.median(diff[:, 2])) <= 2


def test_the_robust_texture_is_what_most_frames_show(tracked, redder):
    result, _, _ = tracked
    video, old, model = redder
    camera, estimates = result.analysis.camera, result.analysis.frames
    new = robust_texture(model, camera, (176, 144), estimates, video, old)
    diff = _red_shift(new, old)
    # solved for the decoder's bilinear sampling: the shift comes back closer than the mean's
    assert np.median(diff[:, 0]) >= 38, np.median(diff[:, 0])
    assert abs(np.median(diff[:, 1])) <= 1 and abs(np.median(diff[:, 2])) <= 1
    # one frame of the ten shows a black square over the face: the mean takes a tenth of it,
    # the robust texture next to nothing
    covered = [f.copy() for f in video]
    covered[8][40:100, 60:120] = 0
    mean = mean_texture(model, camera, (176, 144), estimates, covered, old).astype(int)
    robust = robust_texture(model, camera, (176, 144), estimates, lambda: iter(covered), old)
    mean_moved = np.abs(mean - mean_texture(model, camera, (176, 144), estimates, video, old))
    robust_moved = np.abs(robust.astype(int) - new.astype(int))
    hit = mean_moved.max(axis=2) > 2  # the texels the square moved the mean
    assert hit.sum() > 500 and mean_moved.max() > 10, (hit.sum(), mean_moved.max())
    m, r = np.median(mean_moved[hit]), np.median(robust_moved[hit])
    assert r < m / 3, (r, m, np.percentile(robust_moved[hit], 90), hit.sum())
    with pytest.raises(AnalysisError, match="reads the frames twice"):
        robust_texture(model, camera, (176, 144), estimates, iter(video), old)


def test_bad_input_is_a_clear_error(tracked):
    result, frames, folder = tracked
    model = load_model(str(folder / "car.wrl"))
    camera, estimates = result.analysis.camera, result.analysis.frames
    texture = np.zeros((256, 256, 3), np.uint8)
    with pytest.raises(AnalysisError, match="an \\(H, W, 3\\) image"):
        mean_texture(model, camera, (176, 144), estimates, frames, texture[..., 0])
    small = [f[:100] for f in frames]
    with pytest.raises(AnalysisError, match="frame 0 is 176x100, the analysis's video 176x144"):
        mean_texture(model, camera, (176, 144), estimates, small, texture)
    with pytest.raises(AnalysisError, match="none of its parts"):
        mean_texture(model, camera, (176, 144), estimates, frames, texture, parts=("NOSE",))
    with pytest.raises(AnalysisError, match="only a head fitted to the video"):
        retexture(replace(result, fitted=[]), frames, (176, 144))
    assert MIN_WEIGHT > 0


def test_analyze_writes_the_mean_texture_unless_told_the_anchor(tmp_path, fits, capsys):
    """``vtts analyze`` in this process (test_analyze_cli runs the command) on frames 16–21:
    both runs fit the same anchor frame, :data:`ANCHOR`, the fit ``tracked`` made when it ran
    first (conftest.py's ``SharedFits``)."""
    from vtts.cli import main

    clip = tmp_path / "clip"
    clip.mkdir()
    frames = _frames(22)[16:]
    for i, frame in enumerate(frames):
        Image.fromarray(frame).save(clip / f"f{i}.png")
    textures = {}
    for how in ("mean", "anchor"):
        out = tmp_path / how / "talk.fbs"
        args = ["--texture", how] if how == "anchor" else []
        capsys.readouterr()
        with fits.sharing():
            code = main(["analyze", str(clip), "-o", str(out), "--track", *args])
        stdout, stderr = capsys.readouterr()
        assert code == 0, stderr
        # the summary says what the texture is
        assert ("-frame.png: what 6 frames show)" in stdout) == (how == "mean"), stdout
        textures[how] = np.asarray(Image.open(out.with_name("talk-model-frame.png")))
        assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]
    # --texture anchor: one of the frames as it is; the mean: close to it, but not it
    assert any(np.array_equal(textures["anchor"], frame_texture(f)) for f in frames)
    diff = np.abs(textures["mean"].astype(int) - textures["anchor"].astype(int))
    assert 0 < diff.mean() < 3, diff.mean()


def test_the_surface_under_each_pixel(tracked):
    from vtts.analysis import Estimator

    result, frames, folder = tracked
    model = load_model(str(folder / "car.wrl"))
    estimator = Estimator(model, size=(176, 144), camera=result.analysis.camera)
    fe = result.analysis.frames[ANCHOR // 2]  # the frame the head was fitted to
    estimator.params, estimator.translation = fe.params.copy(), fe.translation.copy()
    pixels, tri, lam = estimator.surface()
    inner, _, _ = estimator.surface(shrink=2)
    assert len(pixels) == len(tri) == len(lam) > 2000
    assert 0 < len(inner) < len(pixels)
    assert set(map(tuple, inner)) <= set(map(tuple, pixels))
    np.testing.assert_allclose(lam.sum(axis=1), 1.0, atol=1e-9)
    # each ray meets the triangle its pixel shows (the rasterizer's single precision puts a
    # pixel centre a hair outside its triangle at times)
    assert lam.min() > -0.02 and lam.max() < 1.02, (lam.min(), lam.max())
    # the points the rays meet project back onto their pixels
    positions = estimator.geometry.positions(estimator.params, estimator.translation)
    points = np.einsum("nm,nmk->nk", lam, positions[estimator.geometry.faces[tri]])
    xy = estimator.camera.project(points)
    np.testing.assert_allclose(xy, pixels[:, ::-1] + 0.5, atol=1e-6)
