"""Self-reenactment of talking photos (issue 41, "Targets"): each clip of
``tests/data/video/`` drives a talking photo of its own first frame.

Per clip: a head is fitted on the first frame and the clip tracked from there as ``vtts analyze
VIDEO --model auto --track --faps paper17,19-26`` does (:func:`vtts.analysis.track.track`, the
tracking mode, every frame, ``anchor=0``; the paper's 17 FAPs and the eyes' lids and gaze, which
a talking photo shows: :data:`FAPS`); the head is the one fitted to that frame (textured with
it, not retextured from the later frames); the video's own FAPs and head translation
(``tracked.analysis.stream``) drive it rendered as a talking photo of the first frame
(:class:`vtts.render.talking_photo.TalkingPhoto`, as ``vtts play x.fbs --model x-model.wrl
--viewpoint photo --background photo``), at the video's camera. Every frame after the first is
measured against the camera frame:

* **full-frame PSNR** (RGB; the sequence's: the mean squared error over frames),
* **SSIM** (``skimage.metrics.structural_similarity``, over RGB, mean over frames),
* **Equation 18**: the luminance PSNR over the camera face's oval
  (:func:`vtts.analysis.landmark_quality.oval_psnr`; median over frames),

beside two baselines: the **frozen first frame** (the photo that does not talk), and the **head
over a plain background** (the whole fitted head, hair cap, ears and neck included, rendered
as ``vtts play … --viewpoint photo`` draws it, over the renderer's default grey-blue).

Target (issue 41): better full-frame PSNR than the frozen first frame on **every** clip, by
at least 2 dB median over clips. Rows per clip, then the median and the worst clip of the
**development** part and, apart, of the **set-aside** part (never tuned on, never looked at).

Pictures (development clips only), written to ``VTTS_BENCH_OUT`` (default: a new temporary
folder, printed): ``CLIP-reenact.png``, a few frames in rows: camera | talking photo | frozen
first frame | head over plain background.

Environment: ``VTTS_BENCH_FRAMES=N`` each clip's first N frames, ``VTTS_BENCH_CLIPS=a,b`` only
those clips (a quick look: the figures are then not the benchmark's); ``VTTS_BENCH_FAPS=LIST``
estimates ``--faps LIST`` instead of :data:`FAPS` (``paper17``: ``vtts analyze``'s default set,
without the eyes).
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

BENCH = "reenact"
ROOT = Path(__file__).resolve().parents[1]
VIDEOS = ROOT / "tests" / "data" / "video"
DEVELOPMENT = ("akiyo_cif", "carphone_qcif", "lp_d0", "lp_d3", "lp_d12", "lp_d13")
SET_ASIDE = ("lp_d9", "lp_d18", "lp_d20")
PARTS = (("development", DEVELOPMENT), ("set-aside", SET_ASIDE))
#: The ways of showing the clip compared: the talking photo and the two baselines.
METHODS = ("talking photo", "frozen first frame", "head over plain background")
#: The FAPs the clips are tracked with (``--faps``' syntax): the paper's 17 and the eyes (lids
#: 19–22, gaze 23–26). ``vtts analyze`` leaves the eyes out by default (their bits pay on some
#: clips only: docs/analysis.md); a talking photo that should look like the video shows them.
FAPS = "paper17,19-26"
#: The gain over the frozen first frame (dB, full-frame PSNR, median over clips) asked for.
TARGET_GAIN_DB = 2.0
#: Frames per clip on the picture, and each picture's height (pixels).
SHEET_FRAMES = 4
SHEET_HEIGHT = 200


@dataclass
class Clip:
    """One clip's figures: per method, per frame measured."""

    clip: str
    size: tuple[int, int]
    frames: int = 0
    mse: dict = field(default_factory=lambda: {m: [] for m in METHODS})
    ssim: dict = field(default_factory=lambda: {m: [] for m in METHODS})
    eq18: dict = field(default_factory=lambda: {m: [] for m in METHODS})
    seconds: float = math.nan  # the talking photo's frames, wall time per frame
    tracked: int = 0

    def psnr(self, method: str) -> float:
        mse = float(np.mean(self.mse[method]))
        return math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)

    def mean_ssim(self, method: str) -> float:
        return float(np.mean(self.ssim[method]))

    def median_eq18(self, method: str) -> float:
        v = np.array(self.eq18[method], np.float64)
        v = v[np.isfinite(v)]
        return float(np.median(v)) if v.size else math.nan


def run() -> list[dict]:
    from bench_people import _unknowns, chosen_clips, out_folder  # noqa: I001  (bench/ on the path)

    out = out_folder("vtts-bench-reenact-")
    limit, chosen = chosen_clips()
    unknowns = _unknowns(os.environ.get("VTTS_BENCH_FAPS", FAPS))
    print(f"  bench_reenact: FAPs {os.environ.get('VTTS_BENCH_FAPS', FAPS)}", file=sys.stderr)
    unknown = sorted(set(chosen) - set(DEVELOPMENT) - set(SET_ASIDE))
    if unknown:
        raise ValueError(f"VTTS_BENCH_CLIPS names no clip of {VIDEOS}: {unknown}")
    print(f"  bench_reenact: pictures in {out}", file=sys.stderr)
    rows: list[dict] = []
    results: dict[str, Clip] = {}
    for clip in (c for c in (*DEVELOPMENT, *SET_ASIDE) if not chosen or c in chosen):
        t0 = time.perf_counter()
        pictures = out if clip in DEVELOPMENT else None
        results[clip] = measured = _clip(clip, limit, pictures, unknowns)
        print(f"  bench_reenact: {clip}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        rows += _clip_rows(measured)
    for part, members in PARTS:
        done = [results[c] for c in members if c in results]
        if done:
            rows += _summary_rows(part, done)
    return rows


def _row(case: str, value, unit: str, target: str = "", ok=None) -> dict:
    return {"benchmark": BENCH, "case": case, "value": value, "unit": unit,
            "target": target, "ok": ok}  # fmt: skip


def _clip(clip: str, limit: int | None, pictures: Path | None, unknowns=None) -> Clip:
    """``clip`` tracked from its first frame (estimating ``unknowns``, None: the default set)
    and replayed as a talking photo of that frame."""
    from skimage.metrics import structural_similarity

    from vtts.analysis.landmark_quality import camera_landmarks, oval_mask, oval_psnr
    from vtts.analysis.track import track
    from vtts.analysis.video import read_video
    from vtts.animate.fapstream import head_roots, stream_params
    from vtts.fit.segment import person_probability
    from vtts.render import FaceRenderer
    from vtts.render.talking_photo import PHOTO_VIEWPOINT, TalkingPhoto, TalkingPhotoOptions

    video = read_video(VIDEOS / f"{clip}.mp4")
    frames = [f for i, f in enumerate(video.frames()) if limit is None or i < limit]
    h, w = frames[0].shape[:2]
    result = Clip(clip, (w, h), len(frames))
    sheet_at = set(np.linspace(1, len(frames) - 1, SHEET_FRAMES).round().astype(int).tolist())
    sheet: dict[int, list[np.ndarray]] = {k: [frames[k]] for k in sheet_at}
    with tempfile.TemporaryDirectory(prefix="vtts-bench-reenact-") as tmp:
        options = {} if unknowns is None else {"unknowns": unknowns}
        tracked = track(frames, fps=video.fps, model_path=Path(tmp) / f"{clip}-model.wrl",
                        tracking=True, anchor=0, **options)  # fmt: skip
        model = tracked.model
        result.tracked = len(tracked.analysis.frames)
        stream = tracked.analysis.stream(clip, fapu=model.fapu)
        params = stream_params(stream, model.tables.adts).params
        n = min(len(params), len(frames))
        ovals = []
        for k in range(n):
            marks = camera_landmarks(frames[k])
            ovals.append(None if marks is None else oval_mask(marks, (w, h)))

        def measure(method: str, k: int, shown: np.ndarray) -> None:
            camera = frames[k]
            diff = camera.astype(np.float64) - shown.astype(np.float64)
            result.mse[method].append(float(np.mean(diff**2)))
            result.ssim[method].append(float(structural_similarity(
                camera, shown, channel_axis=2, data_range=255)))  # fmt: skip
            oval = ovals[k]
            result.eq18[method].append(math.nan if oval is None else oval_psnr(camera, shown, oval))
            if k in sheet:
                sheet[k].append(shown)

        def roots_of(renderer) -> np.ndarray | None:
            if stream.translation is None:
                return None
            return head_roots(renderer.model_matrix(0), stream.translation, model.fapu)

        # one renderer after the other: the GL context holds one scene at a time
        # as --background photo makes it: the person warped over the photo's still background
        options = TalkingPhotoOptions(segment=person_probability)
        with TalkingPhoto(model, options=options) as tp:
            roots = roots_of(tp)
            spent = 0.0
            for k in range(1, n):
                t0 = time.perf_counter()
                shown = tp.render(params[k], roots=None if roots is None else [roots[k]])
                spent += time.perf_counter() - t0
                measure(METHODS[0], k, shown)
            result.seconds = spent / max(n - 1, 1)
        for k in range(1, n):
            measure(METHODS[1], k, frames[0])
        with FaceRenderer(model, size=(w, h), viewpoint=PHOTO_VIEWPOINT) as r:
            roots = roots_of(r)
            for k in range(1, n):
                shown = r.render(params[k], roots=None if roots is None else [roots[k]])
                measure(METHODS[2], k, shown)
    if pictures is not None:
        _picture(pictures / f"{clip}-reenact.png", [sheet[k] for k in sorted(sheet)])
    return result


def _picture(path: Path, rows: list[list[np.ndarray]]) -> None:
    """Rows of camera | talking photo | frozen | plain head, each scaled to
    :data:`SHEET_HEIGHT`."""
    from PIL import Image

    def scaled(image: np.ndarray) -> np.ndarray:
        h, w = image.shape[:2]
        size = (max(1, round(w * SHEET_HEIGHT / h)), SHEET_HEIGHT)
        return np.asarray(Image.fromarray(image[..., :3]).resize(size, Image.Resampling.LANCZOS))

    lines = [np.concatenate([scaled(im) for im in row], axis=1) for row in rows if len(row) == 4]
    if lines:
        Image.fromarray(np.concatenate(lines, axis=0)).save(path)


def _clip_rows(r: Clip) -> list[dict]:
    w, h = r.size
    base = f"{r.clip} ({w}x{h}, {r.frames} frames)"
    rows = []
    for m in METHODS:
        rows.append(_row(f"{base}: {m}: full-frame PSNR", round(r.psnr(m), 2), "dB"))
        rows.append(_row(f"{base}: {m}: SSIM, mean", round(r.mean_ssim(m), 4), ""))
        rows.append(_row(f"{base}: {m}: Eq. 18 (Y, face oval), median", round(r.median_eq18(m), 2),
                         "dB"))  # fmt: skip
    gain = r.psnr(METHODS[0]) - r.psnr(METHODS[1])
    rows.append(_row(f"{base}: talking photo over the frozen first frame, full-frame PSNR",
                     round(gain, 2), "dB", "> 0", gain > 0))  # fmt: skip
    rows.append(_row(f"{base}: talking photo, time per frame (render, warp, compose; wall)",
                     round(1000 * r.seconds, 1), "ms"))  # fmt: skip
    return rows


def _summary_rows(part: str, done: list[Clip]) -> list[dict]:
    """Median and worst clip of one part."""
    base = f"{part} part ({len(done)} clips)"
    rows = []
    figures = [
        ("full-frame PSNR", "dB", lambda r, m: r.psnr(m)),
        ("SSIM", "", lambda r, m: r.mean_ssim(m)),
        ("Eq. 18 median", "dB", lambda r, m: r.median_eq18(m)),
    ]
    for what, unit, value in figures:
        for m in METHODS:
            v = np.array([value(r, m) for r in done], np.float64)
            digits = 4 if unit == "" else 2
            rows.append(_row(f"{base}: {m}: {what}, median over clips",
                             round(float(np.nanmedian(v)), digits), unit))  # fmt: skip
            rows.append(_row(f"{base}: {m}: {what}, worst clip", round(float(np.nanmin(v)), digits),
                             unit))  # fmt: skip
    gains = np.array([r.psnr(METHODS[0]) - r.psnr(METHODS[1]) for r in done])
    med = float(np.median(gains))
    rows.append(_row(f"{base}: talking photo over the frozen first frame, median over clips",
                     round(med, 2), "dB", f">= {TARGET_GAIN_DB:g}",
                     med >= TARGET_GAIN_DB))  # fmt: skip
    worst = int(np.argmin(gains))
    rows.append(_row(f"{base}: talking photo over the frozen first frame, worst clip "
                     f"({done[worst].clip})", round(float(gains[worst]), 2), "dB", "> 0",
                     bool(gains[worst] > 0)))  # fmt: skip
    return rows


if __name__ == "__main__":
    for row in run():
        print(f"{row['case']}: {row['value']} {row['unit']} {row['target']} {row['ok']}")
