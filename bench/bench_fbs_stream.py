"""Streamed ``.fbs`` vs the whole-file arithmetic coder: bits, and the latency of the framing.

A streamed bitstream (:class:`vtts.fap.coding.StreamEncoder`) pays for being decodable frame by
frame: predictor pairs fixed in advance (:func:`~vtts.fap.coding.paired_predictors`) instead of
chosen from the whole stream, each packet's length (1 byte), the range coder ended per packet
(the fewest bytes, ~1 more a frame) and a CRC-8 (1 byte), and a 9-byte end marker. Rows:

- bits/frame of the whole-file arithmetic coder and of the stream (headers, CRCs and end
  marker included) on the real ``.fap`` files of ``tests/data/fap`` (Xface, 25 fps, quantizer
  1), on the paper's experiment (three 30 s say-like streams of ``bench_coding``, 17 FAPs at
  12.5 Hz, quantizer 4) and on an analysis of the Akiyo clip (``vtts analyze``'s 17 unknowns,
  ``ANALYZED`` frames; the estimates as ``vtts analyze --stream`` codes them);
- the milliseconds a frame spends in the stream's coding and framing (encode one frame's
  packet; decode it from a pipe-like file object), the latency streaming adds to an estimate.

``VTTS_BENCH_QUICK=1`` analyzes fewer Akiyo frames.
"""

from __future__ import annotations

import io
import os
import sys
import time
from pathlib import Path

import numpy as np

BENCH = "fbs stream"
ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
ANALYZED = 10 if os.environ.get("VTTS_BENCH_QUICK") else 25


def _row(case: str, value: float, unit: str, target: str = "", ok: bool | None = None) -> dict:
    return {"benchmark": "FAP coding, streamed", "case": case, "value": value, "unit": unit,
            "target": target, "ok": ok}  # fmt: skip


def streamed(stream, quantizer: float = 1.0) -> tuple[bytes, float, float]:
    """``stream`` coded frame by frame: the bytes, and the mean seconds a frame takes to encode
    and to decode."""
    from vtts.fap.coding import StreamDecoder, StreamEncoder, frame_of, paired_predictors

    faps = sorted(set(np.flatnonzero(stream.mask.any(axis=0)) + 1))
    const = bool(stream.mask[:, [k - 1 for k in faps]].all())
    enc = StreamEncoder(fps=stream.fps, faps=faps, quantizer=quantizer, name=stream.name,
                        translation=stream.translation is not None, constant_mask=const,
                        predictors=paired_predictors(faps))  # fmt: skip
    frames = [frame_of(stream, i) for i in range(stream.n_frames)]
    parts = [enc.header()]
    start = time.perf_counter()
    for f in frames:
        parts.append(enc.frames(f))
    t_enc = (time.perf_counter() - start) / max(len(frames), 1)
    parts.append(enc.end())
    data = b"".join(parts)
    start = time.perf_counter()
    n = sum(1 for _ in StreamDecoder(io.BufferedReader(io.BytesIO(data))))  # type: ignore[arg-type]
    t_dec = (time.perf_counter() - start) / max(n, 1)
    return data, t_enc, t_dec


def _compare(label: str, streams: list, quantizer: float, rate: float | None = None) -> list[dict]:
    from vtts.fap.coding import decode, encode, reconstruct

    whole_bits = stream_bits = frames = 0
    t_enc = t_dec = 0.0
    for s in streams:
        if rate is not None:
            s = s.resample(rate)
        whole = encode(s, quantizer=quantizer)
        data, te, td = streamed(s, quantizer)
        d, r = decode(data), reconstruct(s, quantizer=quantizer)
        assert np.array_equal(d.values, r.values), label  # the same reconstruction
        whole_bits += 8 * len(whole)
        stream_bits += 8 * len(data)
        frames += s.n_frames
        t_enc += te * s.n_frames
        t_dec += td * s.n_frames
    w, st = whole_bits / frames, stream_bits / frames
    fps = streams[0].fps if rate is None else rate
    return [
        _row(f"{label}: whole-file arithmetic", round(w, 1), "bits/frame"),
        _row(f"{label}: streamed", round(st, 1), "bits/frame"),
        _row(f"{label}: streaming costs", round(100 * (st / w - 1), 1), "%"),
        _row(f"{label}: streamed bit rate", round(st * fps / 1000, 3), "kbit/s"),
        _row(
            f"{label}: encode + frame one packet",
            round(1000 * t_enc / frames, 3),
            "ms",
            "≤ 1 ms",
            t_enc / frames <= 1e-3,
        ),  # fmt: skip
        _row(
            f"{label}: decode one packet",
            round(1000 * t_dec / frames, 3),
            "ms",
            "≤ 1 ms",
            t_dec / frames <= 1e-3,
        ),  # fmt: skip
    ]


def akiyo_analysis():
    """The FAP stream ``vtts analyze`` estimates from the first frames of Akiyo (fitted head)."""
    import tempfile

    from vtts.analysis.track import track
    from vtts.analysis.video import read_video

    video = read_video(DATA / "video" / "akiyo_cif.mp4")
    frames = (f for i, f in zip(range(ANALYZED), video.frames(), strict=False))
    with tempfile.TemporaryDirectory() as tmp:
        tracked = track(frames, fps=video.fps, model_path=Path(tmp) / "head.wrl")
    return tracked.analysis.stream("akiyo", fapu=tracked.model.fapu)


def run() -> list[dict]:
    from vtts.fap import read_fap

    sys.path.insert(0, str(ROOT / "bench"))
    from bench_coding import SEEDS, speech_stream

    real = [read_fap(p) for p in sorted((DATA / "fap").glob("*.fap"))]
    rows = _compare(f"(b) {len(real)} real Xface files, 25 fps, quantizer 1", real, 1.0)
    paper = [speech_stream(seed) for seed in SEEDS]
    rows += _compare("(a) 3x30 s say-like, 17 FAPs, 12.5 Hz, quantizer 4", paper, 4.0, 12.5)
    analysis = akiyo_analysis()
    rows += _compare(
        f"Akiyo CIF, {ANALYZED} frames analyzed (17 unknowns), quantizer 1", [analysis], 1.0
    )
    return rows


if __name__ == "__main__":  # pragma: no cover
    for row in run():
        print(f"{row['case']}: {row['value']} {row['unit']}")
