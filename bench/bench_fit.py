"""``adi fit`` (a personalized head from one photo): shape against a known truth, how well the
written head reproduces real photos, time per fit and the size of what it writes.

Synthetic truth: each bundled head (lotta, cybatt) rendered at 512 × 512 through a pinhole of
the fitter's default focal length (:func:`vtts.fit.shape.focal_length`), looking at the centre
of its ``FACE`` from 5 units away, from the front and at 20° yaw, and for seeds 0–2 from each of
those yaws with a random pitch (±6°), yaw jitter (±4°) and distance (4.5–6 units); each picture
is fitted with the *other* head as the generic start. The figure is the RMS distance between the
fitted and the true ``FACE`` points after a similarity alignment (Umeyama: rotation,
translation, uniform scale), as a percentage of the true ``FACE``'s width (x extent). The bar:
closer to the truth than the other bundled head is (the same distance between the two neutral
``FACE`` s, about 1.8 %); the issue's goal is half of that.

Real photos: frames never looked at while the fitter was first developed: Akiyo frames 100 and
250 (352 × 288) and Carphone frames 0 and 60 (176 × 144).
Each is fitted, written, loaded back and measured with :func:`vtts.fit.report.figures`: the
median landmark reprojection error (pixels and % of the eye distance), the face PSNR (the pixels
of skin, eyes and mouth; target ≥ 30 dB) and the skin PSNR (``FACE`` alone) between the photo
and the model rendered at its ``photo`` Viewpoint. A photo where no face is found is a row
without a value.

Portraits (issue 41): the development photos and the first frames of the development clips,
and apart the set-aside ones (:data:`SET_ASIDE_PHOTOS`, :data:`SET_ASIDE_CLIPS`, chosen before
any was looked at; the photos ``lp_s9`` and ``lp_s12`` were set aside until stop 53 and are
development photos since stop 54, 2026-11-29): each fitted, written, loaded back and rendered
at its ``photo`` Viewpoint in the photo's expression; the PSNR over every pixel the model draws
(target ≥ 28 dB) and over the face (≥ 30 dB), per photo and as median and worst of each part.

Time: ``fit_photo`` on the 512 × 512 astronaut photo in this process (median of 3 after a
warm-up; target ≤ 3 s) and the whole ``adi fit`` command as a subprocess (median of 3: Python
start-up, imports, the fit and writing the files); the size of the files it writes.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import tempfile
import time
import warnings
from itertools import islice
from pathlib import Path

import numpy as np
from PIL import Image

BENCH = "fit"
ROOT = Path(__file__).resolve().parents[1]
PHOTOS = ROOT / "tests" / "data" / "photos"
VIDEOS = ROOT / "tests" / "data" / "video"
SIZE = 512
DISTANCE = 5.0
YAWS = (0.0, 20.0)
SEEDS = (0, 1, 2)
PITCH_JITTER = 6.0
YAW_JITTER = 4.0
DISTANCES = (4.5, 6.0)
#: (truth, generic start): each head fitted from the other.
PAIRS = (("lotta", "cybatt"), ("cybatt", "lotta"))
#: Held-out video frames: (case name, video, frame numbers).
HELD_OUT = (("akiyo", "akiyo_cif.mp4", (100, 250)), ("carphone", "carphone_qcif.mp4", (0, 60)))
#: Portraits (issue 41): the development photos and clips (whose first frame is fitted), and the
#: set-aside ones, chosen before any was looked at, never looked at while tuning, reported apart.
#: ``lp_s9`` and ``lp_s12`` were set aside until stop 53 (their untuned figures recorded at stops
#: 51-54) and are development photos since stop 54: the issue names all of its photos as the
#: development set.
DEV_PHOTOS = ("akiyo_frame0.png", "astronaut.png", "lp_s1.jpg", "lp_s2.jpg", "lp_s42.jpg",
              "lp_s7.jpg", "lp_s9.jpg", "lp_s12.jpg")  # fmt: skip
SET_ASIDE_PHOTOS: tuple[str, ...] = ()
DEV_CLIPS = ("akiyo_cif", "carphone_qcif", "lp_d0", "lp_d3", "lp_d12", "lp_d13")
SET_ASIDE_CLIPS = ("lp_d9", "lp_d18", "lp_d20")
#: Everything the model draws at the photo's view (alpha over transparent) against the photo.
TARGET_DRAWN_PSNR = 28.0
TARGET_PSNR = 30.0
TARGET_SECONDS = 3.0
RUNS = 3


def umeyama(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """``src (n, 3)`` moved onto ``dst (n, 3)`` by the similarity (rotation, translation,
    uniform scale) of least squared distance (Umeyama 1991)."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    u, d, vt = np.linalg.svd(b.T @ a / len(src))
    s = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[-1] = -1  # a reflection is no pose
    rotation = u @ np.diag(s) @ vt
    scale = float(d @ s) / float(np.mean(np.sum(a**2, axis=1)))
    return scale * a @ rotation.T + mu_d


def shape_error(fitted: np.ndarray, truth: np.ndarray) -> float:
    """RMS distance of ``fitted (n, 3)`` to ``truth (n, 3)`` after a similarity alignment, as %
    of the truth's width (x extent)."""
    aligned = umeyama(fitted, truth)
    rms = math.sqrt(float(np.mean(np.sum((aligned - truth) ** 2, axis=1))))
    return 100 * rms / float(np.ptp(truth[:, 0]))


def quiet_fit(image: np.ndarray, **kw):
    from vtts.fit import fit_photo

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_photo(image, **kw)


def views() -> list[tuple[str, float, float, float]]:
    """(case name, yaw°, pitch°, distance) of the synthetic views."""
    out = [(f"yaw {yaw:.0f}°", yaw, 0.0, DISTANCE) for yaw in YAWS]
    for yaw in YAWS:
        for seed in SEEDS:
            rng = np.random.default_rng(seed)
            pitch = rng.uniform(-PITCH_JITTER, PITCH_JITTER)
            y = yaw + rng.uniform(-YAW_JITTER, YAW_JITTER)
            dist = rng.uniform(*DISTANCES)
            out.append(
                (f"yaw {yaw:.0f}° seed {seed} ({y:+.1f}°/{pitch:+.1f}°/{dist:.2f})", y, pitch, dist)
            )
    return out


def render_truth(model, yaw: float, pitch: float, dist: float) -> np.ndarray:
    """``model`` at ``SIZE`` × ``SIZE`` seen from ``yaw``/``pitch`` degrees, ``dist`` units from
    its ``FACE``'s centre, through the fitter's default pinhole."""
    from vtts.fit.shape import focal_length
    from vtts.render import FaceRenderer
    from vtts.render.camera import Camera, look_at

    face = model.neutral_points("FACE")
    target = (face.min(axis=0) + face.max(axis=0)) / 2
    a, b = math.radians(yaw), math.radians(pitch)
    eye = target + dist * np.array(
        [math.sin(a) * math.cos(b), math.sin(b), math.cos(a) * math.cos(b)]
    )
    f = focal_length((SIZE, SIZE))
    cam = Camera(f, f, SIZE / 2, SIZE / 2, look_at(eye, target), znear=0.5, zfar=20)
    with FaceRenderer(model, size=(SIZE, SIZE), camera=cam) as r:
        # the renderer centres the model in its world; the camera is in the model's own frame
        r.set_view(dataclasses.replace(cam, pose=r.model_matrix(0) @ cam.pose))
        return r.render(model.params())[..., :3]


def row(case: str, value, unit: str, target: str = "", ok=None) -> dict:
    return {
        "benchmark": BENCH,
        "case": case,
        "value": value,
        "unit": unit,
        "target": target,
        "ok": ok,
    }


def synthetic_rows() -> list[dict]:
    from vtts import load_model
    from vtts.fit.generic import generic_head

    faces = {name: load_model(name).neutral_points("FACE") for name, _ in PAIRS}
    # how far the other bundled head is from each truth: the bar a fit has to beat
    apart = {truth: shape_error(faces[other], faces[truth]) for truth, other in PAIRS}
    rows = [
        row(
            f"shape: {other} neutral FACE vs {truth} (no fit)",
            round(apart[truth], 3),
            "% of FACE width",
        )
        for truth, other in PAIRS
    ]
    errors, percent = [], []
    for truth, other in PAIRS:
        model = load_model(truth)
        for name, yaw, pitch, dist in views():
            image = render_truth(model, yaw, pitch, dist)
            case = f"shape: {truth} photo fitted from {other}, {name}"
            target = f"< {other}–{truth} ({apart[truth]:.1f} %)"
            try:
                head = quiet_fit(image, personality=other)
            except Exception as e:  # noqa: BLE001 - a failed fit is a result
                rows.append(row(case, None, f"failed: {e}", target, False))
                errors.append(math.inf)
                percent.append(math.inf)
                continue
            fitted = generic_head(other).face_points(head.shape.control)
            err = shape_error(fitted, faces[truth])
            errors.append(err / apart[truth])
            percent.append(err)
            rows.append(row(case, round(err, 3), "% of FACE width", target, err < apart[truth]))
    # over both truths the bar differs slightly: summarize as a fraction of each case's bar
    bar = min(apart.values())
    for label, v in (("median", float(np.median(percent))), ("worst", max(percent))):
        rows.append(
            row(
                f"shape: {label} of {len(percent)} fits",
                round(v, 3) if math.isfinite(v) else None,
                "% of FACE width",
                f"< {bar:.1f} % (goal {bar / 2:.1f} %)",
                v < bar,
            )
        )
    ratios = np.array(errors)
    for label, v in (("median", float(np.median(ratios))), ("worst", float(ratios.max()))):
        rows.append(
            row(
                f"shape: {label} of {len(ratios)} fits, as a fraction of the other head's distance",
                round(v, 3) if math.isfinite(v) else None,
                "× (goal 0.5)",
                "< 1",
                v < 1,
            )
        )
    return rows


def held_out_frames() -> list[tuple[str, np.ndarray | None, str]]:
    """(case name, frame or None, why not) of the held-out video frames."""
    from vtts.analysis.video import read_video

    out = []
    for name, file, numbers in HELD_OUT:
        try:
            video = read_video(VIDEOS / file)
            frames = dict(
                (i, f)
                for i, f in enumerate(islice(video.frames(), max(numbers) + 1))
                if i in numbers
            )
        except Exception as e:  # noqa: BLE001 - reported as a row
            frames, why = {}, f"{type(e).__name__}: {e}"
        else:
            why = "the video is shorter"
        for n in numbers:
            frame = frames.get(n)
            size = "" if frame is None else f" {frame.shape[1]}x{frame.shape[0]}"
            out.append((f"{name} frame {n}{size} (held out)", frame, why))
    return out


def photo_rows() -> list[dict]:
    from vtts import load_model
    from vtts.fit.report import figures

    cases = held_out_frames()
    rows, face_psnr, skin_psnr, reproj = [], [], [], []
    for case, image, why in cases:
        if image is None:
            rows.append(row(f"photo {case}", None, f"no frame: {why}", "fitted", False))
            face_psnr.append(-math.inf)
            continue
        try:
            head = quiet_fit(image)
        except Exception as e:  # noqa: BLE001 - no face found is a result
            rows.append(row(f"photo {case}", None, f"{type(e).__name__}: {e}", "fitted", False))
            face_psnr.append(-math.inf)
            continue
        with tempfile.TemporaryDirectory(prefix="vtts-bench-fit-") as tmp:
            head.write(Path(tmp) / "m.wrl")
            model = load_model(Path(tmp) / "m.wrl")
            figs = figures(model, head, image)
        px = figs["reprojection_px"]["median"]
        pct = figs["reprojection_percent_of_eye_distance"]["median"]
        face = figs["psnr_db"].get("face", -math.inf)
        skin = figs["psnr_db"].get("skin", -math.inf)
        face_psnr.append(face)
        skin_psnr.append(skin)
        reproj.append(pct)
        rows += [
            row(f"photo {case}: landmark reprojection, median", round(px, 3), "px"),
            row(f"photo {case}: landmark reprojection, median", round(pct, 3), "% of eye distance"),
            row(
                f"photo {case}: face PSNR (skin+eyes+mouth)",
                round(face, 2),
                "dB",
                f">= {TARGET_PSNR:.0f} dB",
                face >= TARGET_PSNR,
            ),
            row(f"photo {case}: skin PSNR (FACE only)", round(skin, 2), "dB"),
        ]
    n = len(cases)
    if reproj:
        summary = (("reprojection", reproj, "% of eye distance", 3, max),
                   ("skin PSNR", skin_psnr, "dB", 2, min))  # fmt: skip
        for name, values, unit, digits, worst in summary:
            rows += [
                row(f"photos: {name}, median of {len(values)} fitted",
                    round(float(np.median(values)), digits), unit),
                row(f"photos: {name}, worst of {len(values)} fitted",
                    round(worst(values), digits), unit),
            ]  # fmt: skip
    # a photo without a fit counts as the worst face PSNR
    for label, v in (("median", float(np.median(face_psnr))), ("worst", min(face_psnr))):
        rows.append(
            row(
                f"photos: face PSNR, {label} of {n} (unfitted count as worst)",
                round(v, 2) if math.isfinite(v) else None,
                "dB",
                f">= {TARGET_PSNR:.0f} dB",
                v >= TARGET_PSNR,
            )
        )
    return rows


def portrait_cases(photos, clips, label: str) -> list[tuple[str, np.ndarray | None, str]]:
    """(case name, image or None, why not) of ``photos`` and the first frames of ``clips``."""
    from vtts.analysis.video import read_video
    from vtts.fit import load_photo

    out: list[tuple[str, np.ndarray | None, str]] = []
    for name in photos:
        image, _ = load_photo(PHOTOS / name)
        out.append((f"{label} photo {name} {image.shape[1]}x{image.shape[0]}", image, ""))
    for name in clips:
        try:
            frame = next(iter(read_video(VIDEOS / f"{name}.mp4").frames()))
        except Exception as e:  # noqa: BLE001 - reported as a row
            out.append((f"{label} clip {name} frame 0", None, f"{type(e).__name__}: {e}"))
            continue
        out.append((f"{label} clip {name} frame 0 {frame.shape[1]}x{frame.shape[0]}", frame, ""))
    return out


def portrait_rows() -> list[dict]:
    """Issue 41: everything the model draws at the photo's view (in the photo's expression,
    over a transparent background: the pixels it covers) against the photo, and the face alone
    (skin, eyes, mouth), on the development portraits and apart on the set-aside ones."""
    from vtts import load_model
    from vtts.fit.report import figures

    rows = []
    for label, photos, clips in (("development", DEV_PHOTOS, DEV_CLIPS),
                                 ("set-aside", SET_ASIDE_PHOTOS, SET_ASIDE_CLIPS)):  # fmt: skip
        drawn, faces = [], []
        for case, image, why in portrait_cases(photos, clips, label):
            if image is None:
                rows.append(row(case, None, f"no frame: {why}", "fitted", False))
                drawn.append(-math.inf)
                faces.append(-math.inf)
                continue
            try:
                head = quiet_fit(image)
            except Exception as e:  # noqa: BLE001 - no face found is a result
                rows.append(row(case, None, f"{type(e).__name__}: {e}", "fitted", False))
                drawn.append(-math.inf)
                faces.append(-math.inf)
                continue
            with tempfile.TemporaryDirectory(prefix="vtts-bench-fit-") as tmp:
                head.write(Path(tmp) / "m.wrl")
                figs = figures(load_model(Path(tmp) / "m.wrl"), head, head.photo)
            a = figs["psnr_db"].get("head", -math.inf)
            f = figs["psnr_db"].get("face", -math.inf)
            drawn.append(a)
            faces.append(f)
            rows += [
                row(f"{case}: all drawn PSNR", round(a, 2), "dB",
                    f">= {TARGET_DRAWN_PSNR:.0f} dB", a >= TARGET_DRAWN_PSNR),
                row(f"{case}: face PSNR", round(f, 2), "dB", f">= {TARGET_PSNR:.0f} dB",
                    f >= TARGET_PSNR),
            ]  # fmt: skip
        for what, values, target in (("all drawn", drawn, TARGET_DRAWN_PSNR),
                                     ("face", faces, TARGET_PSNR)):  # fmt: skip
            for how, v in (("median", float(np.median(values))), ("worst", min(values))):
                rows.append(
                    row(f"{label} portraits: {what} PSNR, {how} of {len(values)}",
                        round(v, 2) if math.isfinite(v) else None, "dB",
                        f">= {target:.0f} dB", v >= target)
                )  # fmt: skip
    return rows


def timing_rows() -> list[dict]:
    image = np.asarray(Image.open(PHOTOS / "astronaut.png").convert("RGB"))
    quiet_fit(image)  # warm-up: imports, the detector's models, the generic head
    seconds, steps = [], []
    for _ in range(RUNS):
        t0 = time.perf_counter()
        head = quiet_fit(image)
        seconds.append(time.perf_counter() - t0)
        steps.append(head.timings)
    inproc = float(np.median(seconds))
    adi = Path(sys.executable).with_name("adi")
    cli, sizes, failure = [], {}, ""
    with tempfile.TemporaryDirectory(prefix="vtts-bench-fit-") as tmp:
        out = Path(tmp) / "me.wrl"
        for _ in range(RUNS):
            t0 = time.perf_counter()
            done = subprocess.run(
                [str(adi), "fit", str(PHOTOS / "astronaut.png"), "-o", str(out)],
                capture_output=True,
                text=True,
                cwd=ROOT,
            )
            if done.returncode != 0:
                failure = (done.stderr.strip().splitlines() or ["?"])[-1]
                break
            cli.append(time.perf_counter() - t0)
        for p in (out, out.with_suffix(".adt"), out.with_name("me-face.png")):
            if p.is_file():
                sizes[p.suffix] = p.stat().st_size / 1024
    rows = [
        row(
            f"time: fit_photo in-process, astronaut {SIZE}x{SIZE} (median of {RUNS})",
            round(inproc, 3),
            "s",
            f"<= {TARGET_SECONDS:.0f} s",
            inproc <= TARGET_SECONDS,
        ),
        row(
            f"time: `adi fit` command end to end, subprocess (median of {RUNS})",
            round(float(np.median(cli)), 3) if cli else None,
            "s" if cli else f"failed: {failure}",
        ),
    ]
    for step in ("landmarks", "shape", "head", "texture"):
        v = float(np.median([t.get(step, math.nan) for t in steps]))
        rows.append(row(f"time: fit_photo step '{step}' (median of {RUNS})", round(v, 3), "s"))
    for suffix, label in (
        (".wrl", "scene .wrl"),
        (".adt", "tables .adt"),
        (".png", "texture -face.png"),
    ):
        rows.append(
            row(f"size: {label}", round(sizes[suffix], 1) if suffix in sizes else None, "KB")
        )
    rows.append(row("size: total written", round(sum(sizes.values()), 1) if sizes else None, "KB"))
    return rows


def run() -> list[dict]:
    return synthetic_rows() + portrait_rows() + photo_rows() + timing_rows()
