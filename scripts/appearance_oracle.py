"""How far a texture that changes from frame to frame would take Equation 18: four oracles.

    .venv/bin/python scripts/appearance_oracle.py tests/data/video/lp_d13.mp4

Analyzes the video as ``bench/bench_people.py`` does in the accurate mode (``--model auto``, the
most typical frame as the anchor, the frames the 12.5 Hz stream shows, the robust texture, coded
at 12.5 Hz with ``vtts analyze``'s quantizer) and decodes the ``.fbs`` through the video's
camera, then draws every decoded frame again with a texture made for that frame and measures
Equation 18 (luminance PSNR over the camera face's oval, the decoded frame laid over the camera
frame: :mod:`vtts.analysis.landmark_quality`). The texture of a decoded frame is the robust
texture plus a **residual** ``(texels, 3)`` over the texels the head's frame-textured parts can
show (:func:`frame_residuals`: what the camera frame shows there less what the robust texture
draws at the same surface points, averaged per texel with the bilinear weights):

* ``robust`` — no residual: the benchmark's figure;
* ``own`` — each frame's own residual, where the frame shows the texel (a new texture every
  frame: what no stream at 1 kbit/s can carry; bounded by the residual's own blur, one
  splatting);
* ``regressed`` — the residual as a linear function of the decoded frame's parameters
  (:data:`FEATURES`: the jaw, the lips, the lip corners, the head's rotation; per texel, ridge
  least squares over the frames, :func:`regress`): appearance the decoder could derive from the
  FAPs it has, zero bits — fitted on all frames (``regressed``), and, to tell a model of
  appearance from a memory of the clip, on the first half only and measured on the second
  (``regressed_half1``) and the other way round (``regressed_half2``), beside ``robust`` on the
  same frames;
* ``pca_K`` — the residuals' first ``K`` principal components (eigen-textures sent once with
  the model), each frame's coefficients as they are, unquantized (:func:`principal`): what ``K``
  appearance numbers per frame in the stream could at most give.

Prints JSON: per variant the median and worst frame's Equation 18 (dB) and the frames measured.
``--picture OUT.png`` writes one frame of the second half (its middle) as each variant draws it,
laid over the camera frame and cropped to the face: camera | robust | own | regressed |
regressed, half 1 | pca 6, each with its Equation 18.
See docs/analysis.md, "Appearance that changes with the frame (stop 55)".
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: The decoded parameters the ``regressed`` residual is a linear function of, each a sum of
#: ``params`` columns (FAP k at column k − 1): open_jaw; the mid lips; the corners' stretch and
#: raise; the head's pitch, yaw and roll.
FEATURES = {
    "jaw": (2,),
    "upper_lip": (3,),
    "lower_lip": (4,),
    "corners_stretch": (5, 6),
    "corners_raise": (11, 12),
    "head_pitch": (47,),
    "head_yaw": (48,),
    "head_roll": (49,),
}
#: The ridge of :func:`regress`, in frames (each feature standardized): how many frames' worth
#: of evidence holds a texel's coefficients at 0.
RIDGE = 1.0
#: A frame's summed bilinear weight on a texel at which its residual counts whole.
SEEN = 0.5
#: The principal components tried.
PCA_KS = (2, 6)


def frame_residuals(
    samples, rendered: np.ndarray, n: int
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per frame, the residual of each texel and the frame's weight on it.

    ``samples``: :func:`vtts.analysis.texture._samples`'s iterator — per frame ``(index, at (4,
    m), weights (4, m), colors (m, 3))``; ``rendered`` ``(n, 3)`` the texture's texels in the
    same box; ``n`` texels. Returns ``{index: (residual (n, 3) float32, weight (n,) float32)}``:
    the camera pixels less the texture's bilinear sample at the same points, averaged per texel
    with the bilinear weights (0 where the frame shows nothing)."""
    out = {}
    for index, at, weights, colors in samples:
        r = colors - np.einsum("kn,knc->nc", weights, rendered[at])
        weight = np.zeros(n)
        sums = np.zeros((n, 3))
        for k in range(4):
            weight += np.bincount(at[k], weights[k], minlength=n)
            for c in range(3):
                sums[:, c] += np.bincount(at[k], weights[k] * r[:, c], minlength=n)
        out[index] = ((sums / np.maximum(weight, 1e-9)[:, None]).astype(np.float32),
                      weight.astype(np.float32))  # fmt: skip
    return out


def regress(residuals: list[np.ndarray], weights: list[np.ndarray], features: np.ndarray,
            ridge: float = RIDGE) -> np.ndarray:  # fmt: skip
    """Per texel, the residual as ``c₀ + Σ_k f_k · c_k``: weighted ridge least squares over the
    frames. ``residuals`` ``T × (n, 3)``, ``weights`` ``T × (n,)``, ``features`` ``(T, K)``
    (standardized). Returns the coefficients ``(n, K + 1, 3)`` (the constant first; the ridge
    holds the others, not the constant)."""
    t, k = features.shape
    phi = np.hstack([np.ones((t, 1)), features])
    n = len(residuals[0])
    a = np.zeros((n, k + 1, k + 1))
    b = np.zeros((n, k + 1, 3))
    for row, res, w in zip(phi, residuals, weights, strict=True):
        w = w.astype(np.float64)
        a += w[:, None, None] * np.outer(row, row)[None]
        b += w[:, None, None] * row[None, :, None] * res.astype(np.float64)[:, None, :]
    reg = np.eye(k + 1) * ridge
    reg[0, 0] = 1e-6
    return np.linalg.solve(a + reg[None], b)


def principal(residuals: list[np.ndarray], weights: list[np.ndarray], k: int) -> np.ndarray:
    """Each frame's residual through the first ``k`` principal components of them all (each
    counted where its frame shows the texel, :data:`SEEN`): ``(T, n, 3)``."""
    m = np.stack([(r * np.clip(w / SEEN, 0, 1)[:, None]).ravel()
                  for r, w in zip(residuals, weights, strict=True)])  # fmt: skip
    _, _, vt = np.linalg.svd(m, full_matrices=False)
    basis = vt[:k]
    return ((m @ basis.T) @ basis).reshape(len(residuals), -1, 3)


def _upload(renderer, name: str, rgb: np.ndarray) -> None:
    """Replace, in ``renderer``'s GL context, the texture image file ``name``'s texels by ``rgb``
    ``(H, W, 3) uint8`` (the same size), its mipmaps made as vtts makes them. An oracle's tool:
    it reaches into the renderer's scene (the texture the scene builder made for the file)."""
    from OpenGL import GL

    from vtts.render.mipmaps import mip_levels

    textures = renderer._builder._image_textures  # image file → its pyrender texture
    texture = next(t for path, t in textures.items() if Path(path).name == name)
    rgba = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=2)
    GL.glBindTexture(GL.GL_TEXTURE_2D, texture._texid)
    GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
    for level, image in enumerate(mip_levels(np.flip(rgba, axis=0))):
        h, w = image.shape[:2]
        GL.glTexSubImage2D(GL.GL_TEXTURE_2D, level, 0, 0, w, h, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE,
                           np.ascontiguousarray(image))  # fmt: skip
    GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 4)
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("video", type=Path)
    ap.add_argument("--picture", type=Path, default=None)
    args = ap.parse_args(argv)
    from vtts.errors import VttsError

    try:
        print(json.dumps(measure(args.video, args.picture), indent=1))
    except VttsError as e:  # a video that cannot be read or analyzed: said, no traceback
        print(f"appearance_oracle: {e}", file=sys.stderr)
        return 2
    return 0


#: The variants on ``--picture``'s row, after the camera frame.
PICTURED = ("robust", "own", "regressed", "regressed_half1", f"pca_{PCA_KS[-1]}")
#: The height (pixels) of each face on the picture.
PICTURE_HEIGHT = 240


def _picture(path: Path, camera: np.ndarray, drawn: dict, landmarks: np.ndarray) -> None:
    """``path``: the camera frame and each variant's ``(composite, Eq. 18 dB)`` in ``drawn``,
    cropped to the face's landmarks (a fifth of its size around), side by side, labelled."""
    from PIL import Image, ImageDraw

    from vtts.atomic import atomic_path

    (x0, y0), (x1, y1) = landmarks[:, :2].min(0), landmarks[:, :2].max(0)
    pad = 0.2 * max(x1 - x0, y1 - y0)
    h, w = camera.shape[:2]
    box = (max(int(x0 - pad), 0), max(int(y0 - pad), 0),
           min(int(x1 + pad), w), min(int(y1 + pad), h))  # fmt: skip
    panels = [("camera", camera, None)] + [(v, *drawn[v]) for v in PICTURED if v in drawn]
    size = (round(PICTURE_HEIGHT * (box[2] - box[0]) / (box[3] - box[1])), PICTURE_HEIGHT)
    sheet = Image.new("RGB", (size[0] * len(panels), size[1] + 16), "white")
    draw = ImageDraw.Draw(sheet)
    for j, (name, image, db) in enumerate(panels):
        face = Image.fromarray(np.ascontiguousarray(image[..., :3])).crop(box).resize(size)
        sheet.paste(face, (j * size[0], 16))
        draw.text((j * size[0] + 3, 2), name if db is None else f"{name} {db:.1f} dB", fill="black")
    with atomic_path(path) as tmp:
        sheet.save(tmp, format="PNG")


def measure(video: Path, picture: Path | None = None) -> dict:
    from PIL import Image

    from vtts.analysis import texture as tx
    from vtts.analysis.anchor import choose_anchor
    from vtts.analysis.landmark_quality import camera_landmarks, lay_over, measure_frame
    from vtts.analysis.steps import analysis_steps
    from vtts.analysis.track import track
    from vtts.analysis.video import read_video
    from vtts.animate.fapstream import head_roots, stream_params
    from vtts.api.analyze import QUANTIZER
    from vtts.fap.coding import decode, encode
    from vtts.fit.photo import frame_texture_name
    from vtts.render import FaceRenderer

    rate = 12.5
    clip = read_video(video)
    frames, fps = list(clip.frames()), clip.fps
    h, w = frames[0].shape[:2]
    tmp = Path(tempfile.mkdtemp(prefix="vtts-appearance-"))
    anchor = choose_anchor(frames, fps, len(frames), rate=rate)
    tracked = track(frames, fps=fps, model_path=tmp / f"{video.stem}-model.wrl", rate=rate,
                    tracking=False, anchor=anchor)  # fmt: skip
    model = tx.retexture(tracked, frames, (w, h))
    stream = tracked.analysis.stream(video.stem, fapu=model.fapu)
    steps = analysis_steps(tracked.analysis, model, (w, h))
    decoded = decode(encode(stream, rate=rate, steps=steps, quantizer=QUANTIZER))
    params = stream_params(decoded, model.tables.adts).params
    name = frame_texture_name(tracked.fitted[0])
    with Image.open(next(p for p in tracked.fitted if p.name == name)) as im:
        robust = np.asarray(im.convert("RGB")).astype(np.float64)

    estimates = [fe for fe in tracked.analysis.frames if not np.isnan(fe.psnr)]
    box, samples = tx._samples(model, tracked.analysis.camera, (w, h), estimates, frames,
                               robust.shape, tx.FRAME_PARTS)  # fmt: skip
    inside = robust[box.y0 : box.y0 + box.h, box.x0 : box.x0 + box.w].reshape(-1, 3)
    res = frame_residuals(samples, inside, box.n)
    shown = sorted(res)  # camera frames with a residual
    first_decoded = {}
    for i in range(decoded.n_frames):
        first_decoded.setdefault(round(i / decoded.fps * fps), i)
    feats = np.array([[params[first_decoded[k], list(cols)].sum() for cols in FEATURES.values()]
                      for k in shown])  # fmt: skip
    mean, scale = feats.mean(0), feats.std(0) + 1e-9
    z = (feats - mean) / scale
    r_list = [res[k][0] for k in shown]
    w_list = [res[k][1] for k in shown]
    half = len(shown) // 2
    halves = {"regressed": (range(len(shown)), range(len(shown))),
              "regressed_half1": (range(half), range(half, len(shown))),
              "regressed_half2": (range(half, len(shown)), range(half))}  # fmt: skip
    residual_of: dict[str, dict[int, np.ndarray]] = {"robust": {}}
    measured_on: dict[str, set[int]] = {"robust": set(shown), "own": set(shown)}
    residual_of["own"] = {k: r * np.clip(wt / SEEN, 0, 1)[:, None]
                          for k, r, wt in zip(shown, r_list, w_list, strict=True)}  # fmt: skip
    for variant, (fit_on, test_on) in halves.items():
        coef = regress([r_list[t] for t in fit_on], [w_list[t] for t in fit_on], z[list(fit_on)])
        residual_of[variant] = {shown[t]: np.einsum("nkc,k->nc", coef, np.r_[1.0, z[t]])
                                for t in test_on}  # fmt: skip
        measured_on[variant] = {shown[t] for t in test_on}
    for k_pca in PCA_KS:
        through = principal(r_list, w_list, k_pca)
        residual_of[f"pca_{k_pca}"] = dict(zip(shown, through, strict=True))
        measured_on[f"pca_{k_pca}"] = set(shown)

    second = sorted(shown[t] for t in halves["regressed_half1"][1])
    pick = second[len(second) // 2]
    drawn: dict[str, tuple[np.ndarray, float]] = {}
    landmarks = {}
    out: dict = {"video": video.name, "frames_analyzed": len(shown), "variants": {}}
    per_frame: dict[str, dict[int, float]] = {}
    for variant, residuals in residual_of.items():
        eq18: dict[int, float] = {}
        with FaceRenderer(model, size=(w, h), viewpoint=None, camera=tracked.analysis.camera,
                          background="transparent") as r:  # fmt: skip
            roots = None
            if decoded.translation is not None:
                roots = head_roots(r.model_matrix(0), decoded.translation, model.fapu)
            r.apply(r.prepare(params[0], roots=None if roots is None else [roots[0]]))
            r.render()  # the textures on the GPU
            for i in range(decoded.n_frames):
                k = round(i / decoded.fps * fps)
                if k >= len(frames) or k not in measured_on[variant]:
                    continue
                texture = robust.copy()
                if k in residuals:
                    texture[box.y0 : box.y0 + box.h, box.x0 : box.x0 + box.w] += (
                        residuals[k].reshape(box.h, box.w, 3))  # fmt: skip
                _upload(r, name, np.clip(np.round(texture), 0, 255).astype(np.uint8))
                r.apply(r.prepare(params[i], roots=None if roots is None else [roots[i]]))
                rgba = r.render()
                if k not in landmarks:
                    landmarks[k] = camera_landmarks(frames[k])
                m = measure_frame(frames[k], rgba, landmarks[k])
                if m.camera_face:
                    eq18[i] = m.eq18_db
                    if k == pick and variant not in drawn:
                        drawn[variant] = (lay_over(frames[k], rgba), m.eq18_db)
        per_frame[variant] = eq18
    if picture is not None and landmarks.get(pick) is not None:
        _picture(picture, frames[pick], drawn, landmarks[pick])
        out["picture"] = {"path": str(picture), "camera_frame": pick}
    for variant, eq18 in per_frame.items():
        values = np.array(list(eq18.values()))
        robust_same = np.array([per_frame["robust"][i] for i in eq18 if i in per_frame["robust"]])
        out["variants"][variant] = {
            "eq18_median_db": round(float(np.median(values)), 2),
            "eq18_worst_db": round(float(values.min()), 2),
            "robust_on_the_same_frames_db": round(float(np.median(robust_same)), 2),
            "frames": len(values),
        }
    return out


if __name__ == "__main__":
    sys.exit(main())
