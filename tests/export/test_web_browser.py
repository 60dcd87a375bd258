"""The web player in a real browser: Debian's headless Chromium loads the folder that write_web
wrote, served on 127.0.0.1, and what it draws is compared with vtts's own renderer.

- the head's silhouette at three times overlaps vtts render's of the same frames, through the same
  camera, with IoU ≥ 0.95;
- between those times the picture changes where vtts's frames change (the mouth), and nowhere
  else;
- the animation follows the audio clock; several heads can be shown one at a time.

Setup installs chromium (scripts/setup.sh); without it these tests fail, they do not skip.
``VTTS_WEB_SCREENSHOT=docs/web-player.png`` also saves the middle screenshot there (the one
docs/web.md shows).
"""

from __future__ import annotations

import io
import os

import numpy as np
import pytest

from vtts.export.browser import Chromium, find_chromium, serve
from vtts.export.web import write_web
from vtts.render import write_wav

SIZE = (352, 288)
FPS = 30.0
#: The frames compared: neutral, an open "aa", and closed lips (p, b, m) stretched in a smile.
KEYS = {0: {}, 15: {"visemes": {10: 1.0}}, 30: {"visemes": {1: 1.0}, "expressions": {"joy": 1.0}}}
SILHOUETTE_IOU = 0.95
#: A pixel changed when a channel moved by more than this (of 255) between two frames.
CHANGED = 24


@pytest.fixture(scope="module")
def chromium_binary() -> str:
    found = find_chromium()
    if found is None:
        pytest.fail("no chromium: scripts/setup.sh installs Debian's chromium for these tests")
    return found


def track(model) -> np.ndarray:
    """``(31, n_params)``: the key poses of :data:`KEYS`, linear in between."""
    keys = sorted(KEYS)
    poses = np.array([model.params(None, **KEYS[k]) for k in keys])
    frames = np.arange(keys[-1] + 1)
    return np.stack([np.interp(frames, keys, poses[:, j]) for j in range(poses.shape[1])], axis=1)


def rgba(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))


def covered(image: np.ndarray) -> np.ndarray:
    return image[..., 3] >= 128


def changes(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Where two RGBA frames differ: composited over black (uncovered pixels are black), a
    channel moved by more than :data:`CHANGED`."""

    def over_black(x: np.ndarray) -> np.ndarray:
        return x[..., :3].astype(np.float64) * (x[..., 3:] / 255.0)

    return np.abs(over_black(a) - over_black(b)).max(axis=2) > CHANGED


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.logical_or(a, b).sum()
    return float(np.logical_and(a, b).sum() / union) if union else 1.0


@pytest.fixture(scope="module")
def frames(tmp_path_factory, chromium_binary):
    """(vtts's RGBA frames, the player's RGBA screenshots) at the frames of :data:`KEYS`."""
    from vtts.face import load_model
    from vtts.render import FaceRenderer

    model = load_model("cybatt")
    params = track(model)
    folder = tmp_path_factory.mktemp("web") / "player"
    rate = 8000
    t = np.arange(int(rate * 61.0)) / rate  # a minute of audio: the clock test plays its end
    wav = folder.with_name("tone.wav")
    write_wav(wav, (0.1 * np.sin(2 * np.pi * 200 * t)).astype(np.float32), rate)
    write_web(folder, [model], [params], FPS, audio=wav, size=SIZE)
    with FaceRenderer([model], size=SIZE, background="transparent") as renderer:
        ours = {k: renderer.render([params[k]]) for k in KEYS}
    shots = {}
    with serve(folder) as base, Chromium(SIZE, transparent=True, binary=chromium_binary) as b:
        for k in KEYS:
            b.load(f"{base}/index.html?t={k / FPS:.6f}&paused=1&background=transparent")
            shots[k] = rgba(b.screenshot())
    wanted = os.environ.get("VTTS_WEB_SCREENSHOT")
    if wanted:
        from PIL import Image

        Image.fromarray(shots[15]).save(wanted, optimize=True)
    return ours, shots, folder


@pytest.mark.parametrize("key", sorted(KEYS))
def test_silhouette_matches_vtts_render(frames, key):
    ours, shots, _ = frames
    assert shots[key].shape == (SIZE[1], SIZE[0], 4)
    assert covered(ours[key]).sum() > 0.1 * SIZE[0] * SIZE[1]  # a head fills the view
    value = iou(covered(ours[key]), covered(shots[key]))
    assert value >= SILHOUETTE_IOU, f"frame {key}: silhouette IoU {value:.3f}"


@pytest.mark.parametrize("a, b", [(0, 15), (15, 30), (0, 30)])
def test_the_mouth_changes_where_vtts_frames_change(frames, a, b):
    ours, shots, _ = frames
    want, got = changes(ours[a], ours[b]), changes(shots[a], shots[b])
    assert want.sum() > 200, "the poses differ in vtts's frames"
    overlap = iou(want, got)
    # pixels that change in one and not the other lie on the changed region's rim (the two
    # rasterizers round edges and shading differently), never far from it
    assert overlap >= 0.8, f"frames {a}→{b}: changed regions overlap by IoU {overlap:.2f}"
    ys, xs = np.nonzero(want)
    pad = 6
    box = np.zeros_like(want)
    box[ys.min() - pad : ys.max() + pad + 1, xs.min() - pad : xs.max() + pad + 1] = True
    outside = got & ~box
    assert outside.sum() <= 0.02 * got.sum(), (
        f"frames {a}→{b}: the player changed {outside.sum()} pixels where vtts's frames do not"
    )


def test_the_animation_follows_the_audio_clock(frames, chromium_binary):
    """Played from 59.2 s of a minute of audio, the animation's time is the audio's time (the
    samples taken before the audio's last 0.15 s: after it the wall clock takes over)."""
    import time

    _, _, folder = frames
    with serve(folder) as base, Chromium(SIZE, autoplay=True, binary=chromium_binary) as b:
        b.load(f"{base}/index.html?t=59.2&paused=1")
        assert b.evaluate("vttsPlayer.duration") == pytest.approx(61.0, abs=0.05)
        b.evaluate("vttsPlayer.play()")
        samples = []
        for _ in range(8):
            time.sleep(0.1)
            sample = b.evaluate(
                "[vttsPlayer.time(), document.getElementById('audio').currentTime, "
                "vttsPlayer.clockSource()]"
            )
            if sample[1] > 59.85:
                break
            samples.append(sample)
    times = [s[0] for s in samples]
    assert len(samples) >= 3 and times[-1] > 59.4, f"the audio played: {samples}"
    assert times == sorted(times)
    for t, audio, source in samples:
        assert source == "audio"
        assert 0 <= t - audio <= 0.1, f"animation at {t}, audio at {audio}"


def test_one_head_of_several(tmp_path, chromium_binary):
    """With several heads, ``head=NAME`` (the page's head menu) shows that head alone, framed
    in the middle of the view."""
    from scipy import ndimage

    from vtts.face import load_model

    models = [load_model("cybatt"), load_model("lotta")]
    params = [np.zeros((2, len(m.params()))) for m in models]
    folder = write_web(tmp_path / "two", models, params, FPS, size=SIZE)
    heads = {}  # query → [(x of the centre, pixels)] of each head seen, left to right
    with serve(folder) as base, Chromium(SIZE, transparent=True, binary=chromium_binary) as b:
        for head in ("", "lotta"):
            b.load(f"{base}/index.html?t=0&paused=1&background=transparent&head={head}")
            mask = covered(rgba(b.screenshot()))
            labels, n = ndimage.label(mask)
            found = [(ndimage.center_of_mass(labels == i)[1], (labels == i).sum())
                     for i in range(1, n + 1)]  # fmt: skip
            heads[head] = sorted((x, a) for x, a in found if a > 500)
    assert len(heads[""]) == 2, f"both heads, side by side: {heads['']}"
    assert len(heads["lotta"]) == 1, f"one head: {heads['lotta']}"
    (x, area), beside = heads["lotta"][0], heads[""][1][1]
    assert abs(x - SIZE[0] / 2) < 0.1 * SIZE[0]
    assert area >= beside  # framed as vtts frames one head: not smaller than in the row
