"""The analysis report: frames.csv, psnr.png and faps.png."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vtts.analysis.report import (
    CSV_NAME,
    FAPS_PLOT,
    PSNR_PLOT,
    csv_columns,
    faps_figure,
    format_csv,
    mean_psnr,
    psnr_figure,
    write_report,
)
from vtts.analysis.result import Analysis, FrameEstimate
from vtts.errors import AnalysisError
from vtts.face import N_PARAMS
from vtts.render.camera import Camera

UNKNOWNS = (48, "tx", "tz", 3, 12)


def make_analysis(
    n: int = 6, psnr: list[float] | None = None, unknowns: tuple = UNKNOWNS, fps: float = 25.0
) -> Analysis:
    """A made-up analysis: FAP k of frame i is ``k * 10 + i``, tx ``i / 100``, tz ``-i / 50``."""
    frames = []
    for i in range(n):
        params = np.zeros(N_PARAMS)
        for k in range(3, 69):
            params[k - 1] = k * 10 + i + 0.25
        frames.append(
            FrameEstimate(
                index=2 * i,
                time=2 * i / fps,
                params=params,
                translation=np.array([i / 100, 0.5, -i / 50]),
                gain=np.array([1.0, 1.1, 0.9]) + i / 1000,
                offset=np.array([-2.0, 0.0, 3.5]),
                psnr=(psnr[i] if psnr is not None else 30 + i / 3),
                face_pixels=5000 + i,
                iterations=7 + i,
                landmark_px=float("nan") if i == 1 else 0.5 + i / 7,
                held=i == 1,
            )
        )
    return Analysis(frames, unknowns, fps / 2, Camera(300, 300, 32, 24), "head")


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> tuple[Path, list[Path]]:
    """The report of :func:`make_analysis`, written once into a new folder: the folder and the
    files :func:`write_report` said it wrote."""
    out = tmp_path_factory.mktemp("report") / "deep" / "report"
    return out, write_report(make_analysis(), out)


def test_report_files_appear_in_a_new_folder(report):
    out, written = report
    assert written == [out / CSV_NAME, out / PSNR_PLOT, out / FAPS_PLOT]
    assert sorted(p.name for p in out.iterdir()) == sorted([CSV_NAME, PSNR_PLOT, FAPS_PLOT])
    for name in (PSNR_PLOT, FAPS_PLOT):
        with Image.open(out / name) as img:
            assert img.format == "PNG"
            assert img.size[0] >= 400 and img.size[1] >= 200


def test_csv_columns_follow_the_unknowns():
    assert csv_columns(make_analysis()) == [
        "frame",
        "time",
        "psnr_db",
        "face_pixels",
        "iterations",
        "landmark_px",
        "held",
        "fap48",
        "tx",
        "tz",
        "fap3",
        "fap12",
        "gain_r",
        "gain_g",
        "gain_b",
        "offset_r",
        "offset_g",
        "offset_b",
    ]


def test_csv_values_read_back_exactly(report):
    analysis = make_analysis()
    rows = read_csv(report[0] / CSV_NAME)
    assert len(rows) == len(analysis.frames)
    for fe, row in zip(analysis.frames, rows, strict=True):
        assert int(row["frame"]) == fe.index
        assert float(row["time"]) == fe.time
        assert float(row["psnr_db"]) == fe.psnr
        assert int(row["face_pixels"]) == fe.face_pixels
        assert int(row["iterations"]) == fe.iterations
        assert np.isnan(float(row["landmark_px"])) == np.isnan(fe.landmark_px)
        if not np.isnan(fe.landmark_px):
            assert float(row["landmark_px"]) == fe.landmark_px
        assert row["held"] == ("1" if fe.held else "0")
        for k in (48, 3, 12):
            assert float(row[f"fap{k}"]) == fe.params[k - 1]
        assert float(row["tx"]) == fe.translation[0]
        assert float(row["tz"]) == fe.translation[2]
        assert "ty" not in row  # not estimated: no column
        for j, c in enumerate("rgb"):
            assert float(row[f"gain_{c}"]) == fe.gain[j]
            assert float(row[f"offset_{c}"]) == fe.offset[j]


def test_infinite_and_missing_psnr_in_csv():
    text = format_csv(make_analysis(3, psnr=[math.inf, 31.5, math.nan]))
    values = [line.split(",")[2] for line in text.splitlines()[1:]]
    assert values == ["inf", "31.5", "nan"]
    assert math.isinf(float(values[0]))


def test_mean_psnr():
    assert mean_psnr(np.array([30.0, 32.0, math.inf])) == 31.0
    assert mean_psnr(np.array([math.inf, math.inf])) == math.inf
    assert math.isnan(mean_psnr(np.array([])))
    assert mean_psnr(np.array([math.nan, 20.0])) == 20.0


def test_psnr_plot_labels_and_mean():
    fig = psnr_figure(make_analysis())
    (ax,) = fig.axes
    assert "time" in ax.get_xlabel() and "PSNR" in ax.get_ylabel() and "dB" in ax.get_ylabel()
    labels = ax.get_legend_handles_labels()[1]
    assert any(label.startswith("mean 30.83 dB") for label in labels), labels


def test_infinite_psnr_is_clipped_and_annotated(tmp_path):
    analysis = make_analysis(4, psnr=[30.0, math.inf, 35.0, math.inf])
    fig = psnr_figure(analysis)
    (ax,) = fig.axes
    for line in ax.get_lines():
        assert np.all(np.isfinite(np.asarray(line.get_ydata(), float)))
    curve = np.asarray(ax.get_lines()[0].get_ydata(), float)
    assert curve[0] == 30 and curve[2] == 35
    assert curve[1] == curve[3] > 35  # drawn above the best finite value
    texts = [t.get_text() for t in ax.texts]
    assert any("2 frames with infinite PSNR" in t for t in texts), texts
    lo, hi = ax.get_ylim()
    assert lo <= 30 and hi >= curve[1]
    write_report(analysis, tmp_path)  # and it is written
    assert (tmp_path / PSNR_PLOT).stat().st_size > 0


def test_only_infinite_psnr(tmp_path):
    write_report(make_analysis(2, psnr=[math.inf, math.inf]), tmp_path)
    assert read_csv(tmp_path / CSV_NAME)[0]["psnr_db"] == "inf"


def test_one_small_plot_per_fap_and_one_for_the_translation():
    fig = faps_figure(make_analysis())
    shown = [ax for ax in fig.axes if ax.get_visible()]
    titles = [ax.get_title() for ax in shown]
    assert titles == [
        "FAP 48 head_pitch",
        "FAP 3 open_jaw",
        "FAP 12 raise_l_cornerlip",
        "head translation",
    ]
    by_title = dict(zip(titles, shown, strict=True))
    np.testing.assert_allclose(
        by_title["FAP 3 open_jaw"].get_lines()[0].get_ydata(), 30.25 + np.arange(6)
    )
    assert by_title["FAP 3 open_jaw"].get_ylabel() == "MNS"
    assert by_title["FAP 48 head_pitch"].get_ylabel() == "AU"
    assert [line.get_label() for line in by_title["head translation"].get_lines()] == ["tx", "tz"]
    assert all(ax.get_xlabel() == "time (s)" for ax in shown[-4:])


def test_truth_is_drawn_dashed(tmp_path, report):
    analysis = make_analysis()
    truth = analysis.fap_values() + 5.0
    fig = faps_figure(analysis, truth)
    ax = next(ax for ax in fig.axes if ax.get_title() == "FAP 3 open_jaw")
    est, tru = ax.get_lines()
    assert tru.get_linestyle() == "--" and est.get_linestyle() == "-"
    np.testing.assert_allclose(tru.get_ydata(), truth[:, 1])
    write_report(analysis, tmp_path / "b", truth=truth)
    a = np.asarray(Image.open(report[0] / FAPS_PLOT).convert("RGB"))  # without the truth
    b = np.asarray(Image.open(tmp_path / "b" / FAPS_PLOT).convert("RGB"))
    assert a.shape == b.shape and np.any(a != b)


@pytest.mark.parametrize("shape", [(6, 2), (5, 3), (6,), (6, 3, 1)])
def test_truth_of_the_wrong_shape(tmp_path, shape):
    with pytest.raises(AnalysisError, match=r"\(6, 3\)"):
        write_report(make_analysis(), tmp_path / "r", truth=np.zeros(shape))
    assert not (tmp_path / "r").exists()


def test_only_translation_estimated(tmp_path):
    write_report(make_analysis(3, unknowns=("tx", "ty", "tz")), tmp_path)
    assert read_csv(tmp_path / CSV_NAME)[0].keys() >= {"tx", "ty", "tz"}
    fig = faps_figure(make_analysis(3, unknowns=("tx",)))
    assert [ax.get_title() for ax in fig.axes if ax.get_visible()] == ["head translation"]


def test_report_folder_that_is_a_file(tmp_path):
    (tmp_path / "r").write_text("x")
    with pytest.raises(AnalysisError, match="is a file"):
        write_report(make_analysis(), tmp_path / "r")


def test_a_failed_report_leaves_no_temporary_files(tmp_path, monkeypatch):
    import vtts.analysis.report as report

    def broken(*args, **kwargs):
        raise RuntimeError("plotting failed")

    monkeypatch.setattr(report, "faps_figure", broken)
    with pytest.raises(RuntimeError):
        write_report(make_analysis(), tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [CSV_NAME, PSNR_PLOT]


def test_matplotlib_is_imported_only_to_write_a_report():
    code = (
        "import sys, vtts.cli, vtts.analysis.report, vtts.analysis.video;"
        "assert 'matplotlib' not in sys.modules, 'imported'"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
