"""vtts play of a stream with a head translation: the head moves in the frames by what the
translation makes in pixels, in each model's own ES."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from vtts.fap import FapStream
from vtts.fap.coding import encode

from ..in_process import vtts

HEAD = Path(__file__).parents[1] / "data" / "models" / "head.wrl"
SIZE = (176, 144)
# Stand-in MPEG-4 feature points on the test head's FACE_MESH (Candide-3 vertices): upper and
# lower eyelid (3.1, 3.3), the eyes (3.5, 3.6: ES0 = 0.608), the bottom of the nose (9.15), the
# upper lip (2.2) and the mouth corners (8.3, 8.4).
FEATURES = {"3.1": 21, "3.3": 22, "3.5": 21, "3.6": 54, "9.15": 6, "2.2": 40, "8.3": 88, "8.4": 89}


def head_with_fapu(folder: Path, eyes: tuple[int, int] = (21, 54)) -> Path:
    """The test head with feature points (so it has FAPUs), eyes ``(3.5, 3.6)`` as given."""
    folder.mkdir(parents=True, exist_ok=True)
    wrl = folder / "head.wrl"
    shutil.copy(HEAD, wrl)
    points = FEATURES | {"3.5": eyes[0], "3.6": eyes[1]}
    lines = [f"{p} FACE_MESH {v}" for p, v in points.items()]
    # the test head's own tables name one feature point, too few for FAPUs: replace them
    text = HEAD.with_suffix(".adt").read_text(encoding="utf-8").split("#FeaturePoints")[0]
    wrl.with_suffix(".adt").write_text(
        text + "#FeaturePoints\n" + "\n".join(lines) + "\n", encoding="utf-8"
    )
    return wrl


def translated(t: list[list[float]], fps: float = 25.0) -> FapStream:
    n = len(t)
    return FapStream(
        fps=fps, name="moves", values=np.zeros((n, 68)), mask=np.zeros((n, 68)), translation=t
    )


def play(fbs: Path, out: Path, *models: Path) -> subprocess.CompletedProcess:
    argv = ["play", str(fbs), "--size", f"{SIZE[0]}x{SIZE[1]}", "--png-dir", str(out)]
    argv += ["--background", "transparent", "--fps", "25", "--quiet"]
    for m in models:
        argv += ["--model", str(m)]
    return vtts(*argv)


def coverage(folder: Path) -> list[np.ndarray]:
    from PIL import Image

    return [np.asarray(Image.open(p))[..., 3] > 127 for p in sorted(folder.glob("*.png"))]


def centroid(mask: np.ndarray) -> np.ndarray:
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()])


def moved(models: list[Path], offsets: list[np.ndarray]) -> tuple[list[np.ndarray], list]:
    """What play must show: the models rendered at rest, then with each root moved by
    ``offsets[i]`` model units (coverage masks); and each model's centre's pixel shift through
    the camera (a pinhole estimate of the masks' shift)."""
    from vtts.face import load_model
    from vtts.face.miap import N_PARAMS
    from vtts.render import FaceRenderer

    loaded = [load_model(m) for m in models]
    params = [np.zeros(N_PARAMS)] * len(loaded)
    with FaceRenderer(loaded, size=SIZE, background="transparent") as r:
        rest = [r.model_matrix(i) for i in range(len(loaded))]
        roots = [m.copy() for m in rest]
        shifts = []
        for i, off in enumerate(offsets):
            roots[i][:3, 3] += off
            centre = rest[i][:3, 3] + (r.instances[i].lo + r.instances[i].hi) / 2
            a, b = r.camera.project(np.array([centre, centre + off]))
            shifts.append(b - a)
        masks = [
            r.render(params, roots=rest)[..., 3] > 127,
            r.render(params, roots=roots)[..., 3] > 127,
        ]
    return masks, shifts


def test_play_moves_the_head_by_the_translation(tmp_path: Path) -> None:
    from vtts.face import load_model

    wrl = head_with_fapu(tmp_path / "m")
    es = load_model(wrl).fapu.es
    assert es == pytest.approx(0.608 / 1024)
    # 0.2 model units right, then 0.15 up; on the grid of the translation's step (4 ES units)
    t = np.array([[0.0, 0, 0], [0.2 / es, 0, 0], [0, 0.15 / es, 0]])
    t = np.round(t / 4) * 4
    fbs = tmp_path / "moves.fbs"
    fbs.write_bytes(encode(translated(t.tolist())))
    r = play(fbs, tmp_path / "frames", wrl)
    assert r.returncode == 0, r.stderr
    masks = coverage(tmp_path / "frames")
    assert len(masks) == 3 and all(m.sum() > 500 for m in masks)
    c = [centroid(m) for m in masks]
    for frame, axis in ((1, 0), (2, 1)):
        (rest, there), (shift,) = moved([wrl], [t[frame] * es])
        assert np.array_equal(masks[0], rest) and np.array_equal(masks[frame], there)
        # within perspective's difference between the outline's depth and the centre's
        got = c[frame] - c[0]
        assert abs(shift[axis]) > 6 and 0.9 < got[axis] / shift[axis] < 1.1, (got, shift)
        assert abs(got[1 - axis]) < 0.1
    assert c[1][0] > c[0][0] and c[2][1] < c[0][1]  # right, and up (image y grows downwards)


def test_each_model_moves_in_its_own_es(tmp_path: Path) -> None:
    from vtts.face import load_model

    narrow = head_with_fapu(tmp_path / "a")  # ES0 = 0.608
    wide = head_with_fapu(tmp_path / "b", eyes=(16, 49))  # ES0 = 0.782
    es = [load_model(m).fapu.es for m in (narrow, wide)]
    assert es[1] / es[0] == pytest.approx(0.782 / 0.608)
    t = np.array([[0.0, 0, 0], [0, 160, 0]])  # up: the heads stay on their halves
    fbs = tmp_path / "up.fbs"
    fbs.write_bytes(encode(translated(t.tolist())))
    r = play(fbs, tmp_path / "frames", narrow, wide)
    assert r.returncode == 0, r.stderr
    masks = coverage(tmp_path / "frames")
    half = SIZE[0] // 2
    shifts = [
        centroid(masks[1][:, cols]) - centroid(masks[0][:, cols])
        for cols in (slice(0, half), slice(half, None))
    ]
    (rest, there), _ = moved([narrow, wide], [t[1] * es[0], t[1] * es[1]])
    assert np.array_equal(masks[0], rest) and np.array_equal(masks[1], there)
    assert shifts[1][1] < shifts[0][1] - 1 < -5  # the wider-eyed head moves further up


def test_a_model_without_fapus_is_not_moved_and_says_so(tmp_path: Path) -> None:
    fbs = tmp_path / "moves.fbs"
    fbs.write_bytes(encode(translated([[0.0, 0, 0], [400, 0, 0]])))
    r = play(fbs, tmp_path / "frames", HEAD)
    assert r.returncode == 0, r.stderr
    assert "has no FAPUs" in r.stderr and "head translation is ignored" in r.stderr
    a, b = coverage(tmp_path / "frames")
    assert np.array_equal(a, b)
