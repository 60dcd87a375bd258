"""FAP estimation from video (issue 8): the paper's Table 1, harder cases, and speed.

Table 1 of Eisert & Girod: a synthetic CIF sequence of 100 frames rendered from known FAPs
(3, 12, 13, 19, 20, 35, 36, 48, 49, 50) with a camera whose viewing angle (field of view) is
about 25°, estimated every 5th frame; the relative error of each FAP is its mean absolute error
over the 20 estimates divided by its extreme value in the sequence
(:data:`vtts.analysis.synthetic.TABLE1_EXTREMES`). Target: at or below the paper for every FAP,
and a face-area PSNR of at least 70 dB.

The face-area PSNR is the luminance PSNR between each frame and the model rendered from the
estimate as the written FAP stream carries it (integer FAPs) over the pixels the model covers.
When a frame is reproduced exactly its PSNR is infinite; the rows give the median over frames,
how many frames are exact, and the sequence PSNR (from the mean squared error over all frames,
which no exact frame can lift to infinity).

Harder cases, the same sequence and measure: camera noise (Gaussian, σ = 2 gray levels), a
change of light (brightness rising by 25 % over the sequence), the camera turned 25° to the side
of the face, and the second personality (lotta) rendered but analyzed with cybatt, where the
head translation is estimated too (the two heads are framed differently).

Seeded trajectories (issue 15): the same FAPs and extremes on random curves that start away
from neutral (:func:`vtts.analysis.synthetic.random_truth`: every FAP anywhere in its range at
frame 0 — the jaw and eyelids between neutral and their extreme, the others within ± their
extreme), estimated every 5th frame from the first, which starts from neutral. Per FAP the rows
give the median over the seeds and the worst seed, separately for the seeds the first frame's
handling was tuned on (:data:`TUNED_SEEDS`) and for those held out of the tuning
(:data:`HELD_OUT_SEEDS`); and the face-area PSNR of frame 0 (median and worst seed). Before
the first frame's eyelids were searched over their whole range and its pyramid restarted
(:meth:`vtts.analysis.Estimator.estimate`), frame 0 of seed 2 (the left eyelid 460 units
closed) was at 34.7 dB, and of seed 12 at 21.6 dB (the head 0.11 rad off in yaw).

Speed: estimated frames per second on the Table 1 sequence (20 estimates, each starting from the
previous ones, the full pyramid), on this machine's 2 cores. Target ≥ 25 frames/s; the paper:
3.03 s per frame on a 175 MHz SGI O2.
"""

from __future__ import annotations

import time

import numpy as np

BENCH = "analysis"
SIZE = (352, 288)
FRAMES = 100
STEP = 5
PAPER = {3: 0.26, 12: 0.17, 13: 0.19, 19: 0.11, 20: 0.07, 35: 0.04, 36: 0.02, 48: 0.04, 49: 0.41,
         50: 0.20}  # fmt: skip
TARGET_PSNR = 70.0
TARGET_FPS = 25.0
#: Seeds of :func:`vtts.analysis.synthetic.random_truth`: those the first frame's search and
#: restarts were tuned on, and those kept out of the tuning (9–12 were not run before it was
#: done).
TUNED_SEEDS = (1, 2, 3)
HELD_OUT_SEEDS = (4, 5, 6, 7, 8, 9, 10, 11, 12)


def _case(model, truth, *, analyzed_with=None, camera=None, unknowns=None, **render):
    from vtts.analysis import TABLE1_FAPS, Estimator
    from vtts.analysis.synthetic import render_sequence

    frames = render_sequence(model, truth, size=SIZE, camera=camera, **render)
    est = Estimator(
        analyzed_with or model,
        size=SIZE,
        camera=camera if analyzed_with is None else None,
        unknowns=unknowns or TABLE1_FAPS,
    )
    estimates, psnr, mse = [], [], []
    t0 = time.perf_counter()
    for i in range(0, len(frames), STEP):
        fe = est.estimate(frames[i], i)
        estimates.append(fe.params)
        psnr.append(fe.psnr)
        mse.append(0.0 if np.isinf(fe.psnr) else 255.0**2 / 10 ** (fe.psnr / 10))
    seconds = time.perf_counter() - t0
    return np.array(estimates), np.array(psnr), float(np.mean(mse)), seconds


def _seeded(model, seed):
    """Estimates ``(n, N_PARAMS)``, face PSNRs ``(n,)`` and the truth ``(n, N_PARAMS)`` of every
    STEP-th frame of :func:`random_truth`'s sequence for ``seed`` (only those frames rendered)."""
    from vtts.analysis import TABLE1_FAPS, Estimator
    from vtts.analysis.synthetic import random_truth, render_sequence

    truth = random_truth(seed, FRAMES)[::STEP]
    frames = render_sequence(model, truth, size=SIZE)
    est = Estimator(model, size=SIZE, unknowns=TABLE1_FAPS)
    found = [est.estimate(frame, i * STEP) for i, frame in enumerate(frames)]
    return np.array([fe.params for fe in found]), np.array([fe.psnr for fe in found]), truth


def _seeded_rows(model):
    from vtts.analysis import TABLE1_FAPS
    from vtts.analysis.synthetic import TABLE1_EXTREMES, relative_errors

    idx = [f - 1 for f in TABLE1_FAPS]
    extremes = np.array([TABLE1_EXTREMES[f] for f in TABLE1_FAPS])
    errors, first, psnr = {}, {}, []
    for seed in TUNED_SEEDS + HELD_OUT_SEEDS:
        est, frame_psnr, truth = _seeded(model, seed)
        errors[seed] = relative_errors(est[:, idx], truth[:, idx], extremes)
        first[seed] = float(frame_psnr[0])
        psnr += list(frame_psnr)
    seeds = TUNED_SEEDS + HELD_OUT_SEEDS
    span = f"seeds {seeds[0]}–{seeds[-1]}"
    rows = []
    for j, fap in enumerate(TABLE1_FAPS):
        median = float(np.median([errors[s][j] for s in seeds]))
        rows.append(
            {
                "benchmark": BENCH,
                "case": f"{span}: FAP {fap} relative error, median",
                "value": median,
                "unit": "%",
                "target": f"≤ {PAPER[fap]} (paper)",
                "ok": bool(median <= PAPER[fap]),
            }
        )
        for name, group in (("tuned", TUNED_SEEDS), ("held out", HELD_OUT_SEEDS)):
            worst = max(group, key=lambda s: errors[s][j])
            rows.append(
                {
                    "benchmark": BENCH,
                    "case": f"{span}: FAP {fap} relative error, worst {name} seed ({worst})",
                    "value": float(errors[worst][j]),
                    "unit": "%",
                    "target": f"≤ {PAPER[fap]} (paper)",
                    "ok": bool(errors[worst][j] <= PAPER[fap]),
                }
            )
    worst = min(seeds, key=lambda s: first[s])
    finite = np.array(psnr)[np.isfinite(psnr)]
    rows += [
        {
            "benchmark": BENCH,
            "case": f"{span}: face PSNR of frame 0, median of {len(seeds)} seeds",
            "value": float(np.median(list(first.values()))),
            "unit": "dB",
            "target": f"≥ {TARGET_PSNR:.0f}",
            "ok": bool(np.median(list(first.values())) >= TARGET_PSNR),
        },
        {
            "benchmark": BENCH,
            "case": f"{span}: face PSNR of frame 0, worst seed ({worst})",
            "value": first[worst],
            "unit": "dB",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": BENCH,
            "case": f"{span}: face PSNR, median of {len(psnr)} frames",
            "value": float(np.median(psnr)),
            "unit": "dB",
            "target": f"≥ {TARGET_PSNR:.0f}",
            "ok": bool(np.median(psnr) >= TARGET_PSNR),
        },
        {
            "benchmark": BENCH,
            "case": f"{span}: face PSNR, worst frame",
            "value": float(finite.min()) if finite.size else float("inf"),
            "unit": "dB",
            "target": "",
            "ok": None,
        },
    ]
    return rows


def _rows(name, truth, estimates, psnr, mse, *, judge=True):
    from vtts.analysis import TABLE1_FAPS
    from vtts.analysis.synthetic import TABLE1_EXTREMES, relative_errors

    idx = [f - 1 for f in TABLE1_FAPS]
    extremes = np.array([TABLE1_EXTREMES[f] for f in TABLE1_FAPS])
    errors = relative_errors(estimates[:, idx], truth[::STEP][:, idx], extremes)
    rows = []
    for fap, err in zip(TABLE1_FAPS, errors, strict=True):
        rows.append(
            {
                "benchmark": BENCH,
                "case": f"{name}: FAP {fap} relative error",
                "value": float(err),
                "unit": "%",
                "target": f"≤ {PAPER[fap]} (paper)" if judge else f"paper {PAPER[fap]}",
                "ok": bool(err <= PAPER[fap]) if judge else None,
            }
        )
    finite = psnr[np.isfinite(psnr)]
    median = float(np.median(psnr))
    seq = float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)
    rows += [
        {
            "benchmark": BENCH,
            "case": f"{name}: face PSNR, median of {len(psnr)} frames",
            "value": median,
            "unit": "dB",
            "target": f"≥ {TARGET_PSNR:.0f}" if judge else "",
            "ok": bool(median >= TARGET_PSNR) if judge else None,
        },
        {
            "benchmark": BENCH,
            "case": f"{name}: frames reproduced exactly",
            "value": int(np.isinf(psnr).sum()),
            "unit": f"of {len(psnr)}",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": BENCH,
            "case": f"{name}: face PSNR of the sequence (mean MSE)",
            "value": seq,
            "unit": "dB",
            "target": "",
            "ok": None,
        },
        {
            "benchmark": BENCH,
            "case": f"{name}: face PSNR, worst frame",
            "value": float(finite.min()) if finite.size else float("inf"),
            "unit": "dB",
            "target": "",
            "ok": None,
        },
    ]
    return rows


def run() -> list[dict]:
    import vtts
    from vtts.analysis import TABLE1_FAPS
    from vtts.analysis.synthetic import side_camera, table1_truth

    cybatt = vtts.load_model("cybatt")
    truth = table1_truth(FRAMES)
    rows: list[dict] = []

    est, psnr, mse, seconds = _case(cybatt, truth)
    rows += _rows("Table 1", truth, est, psnr, mse)
    fps = len(est) / seconds
    rows.append(
        {
            "benchmark": BENCH,
            "case": "estimation speed at CIF, Table 1 sequence",
            "value": fps,
            "unit": "frames/s",
            "target": f"≥ {TARGET_FPS:.0f}",
            "ok": bool(fps >= TARGET_FPS),
        }
    )

    rows += _seeded_rows(cybatt)

    light = np.linspace(1.0, 1.25, FRAMES)
    cases = [
        ("noise σ=2", dict(noise=2.0)),
        ("light +25 %", dict(light=light)),
        ("camera 25° to the side", dict(camera=side_camera(cybatt, SIZE, 25.0))),
        (
            "lotta analyzed with cybatt",
            dict(
                model=vtts.load_model("lotta"),
                analyzed_with=cybatt,
                unknowns=(*TABLE1_FAPS, "tx", "ty", "tz"),
            ),
        ),
    ]
    for name, kw in cases:
        model = kw.pop("model", cybatt)
        est, psnr, mse, _ = _case(model, truth, **kw)
        rows += _rows(name, truth, est, psnr, mse, judge=False)
    return rows
