"""Shared test fixtures. Tests never read ../shared: their data lives in tests/data/."""

from __future__ import annotations

import contextlib
import copy
import hashlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"


@pytest.fixture
def data_dir() -> Path:
    return DATA


class SharedFits:
    """Heads fitted by :func:`vtts.fit.fit_photo`, made once per photo and options in a
    session (per xdist worker). Within :meth:`sharing` each call gets its own deep copy of the
    head the first call fitted: a fit is seeded and deterministic, the same photo gives the
    same head byte for byte. For tests of what comes after the fit — tracking a video with a
    head fitted to its first face (``track(model_path=...)``) — that fit the same frame again
    and again; not for tests of the fit itself, nor for ones that change what the fit does (a
    patched detector, a warning it gives)."""

    def __init__(self) -> None:
        self.heads: dict[tuple, object] = {}

    @contextlib.contextmanager
    def sharing(self) -> Iterator[None]:
        import vtts.fit
        import vtts.fit.photo

        fit = vtts.fit.photo.fit_photo

        def fit_once(image, **options):
            if options.get("detector") is not None:
                return fit(image, **options)
            pixels = np.ascontiguousarray(image)
            key = (hashlib.sha256(pixels.tobytes()).hexdigest(), pixels.shape,
                   pixels.dtype.str, repr(sorted(options.items())))  # fmt: skip
            if key not in self.heads:
                self.heads[key] = fit(image, **options)
            return copy.deepcopy(self.heads[key])

        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(vtts.fit, "fit_photo", fit_once)
            mp.setattr(vtts.fit.photo, "fit_photo", fit_once)
            yield


@pytest.fixture(scope="session")
def fits() -> SharedFits:
    """The session's :class:`SharedFits` (for a module-scoped fixture: ``with
    fits.sharing(): ...``)."""
    return SharedFits()


@pytest.fixture
def shared_fit(fits: SharedFits) -> Iterator[None]:
    """The test's fits are shared with the session's (:class:`SharedFits`)."""
    with fits.sharing():
        yield


@pytest.fixture(scope="module")
def one_ray_at_a_time(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The module's tests hold the run's Ray lock (a file locked with ``flock``): of the suite's
    files that start a local Ray (its GCS, raylet, workers, Serve's proxy), one at a time, on
    whichever pytest-xdist workers they run. Two Rays starting at once on 2 cores, beside the
    other workers' tests, made Ray Serve's proxy die at its start; a worker waiting here spends
    no CPU, which the other workers use. The file lies in the folder the run's workers share
    (the parent of each worker's base temporary folder), which pytest removes with the run's
    other temporary folders."""
    import fcntl

    path = tmp_path_factory.getbasetemp().parent / "vtts-tests-ray.lock"
    with open(path, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


#: The files that take a worker longest (about 15–60 s each on 2 cores; most wait on Ray, a
#: server, a browser or a rendering): collected first, so that pytest-xdist's ``loadfile``
#: scheduling, which hands files out in collection order, starts them first and the run does
#: not end with one of them alone on a worker. Order within a file is kept.
SLOW_FIRST = (
    "batch/test_ray.py",
    "analysis/test_estimator.py",
    "fit/test_fit.py",
    "analysis/test_stream_cli.py",
    "analysis/test_tracker.py",
    # the other file that starts a local Ray (they take turns: one_ray_at_a_time)
    "serve/test_serve_ray.py",
    "batch/test_pool.py",
    "models/test_bundled.py",
    "serve/test_serve_browser.py",
    "analysis/test_track.py",
    "fit/test_portrait.py",
    "export/test_web_browser.py",
)


def pytest_collection_modifyitems(session, config, items) -> None:
    tests = Path(__file__).parent
    rank = {name: i for i, name in enumerate(SLOW_FIRST)}

    def first(item) -> int:
        path = Path(str(item.fspath))
        try:
            return rank.get(path.relative_to(tests).as_posix(), len(rank))
        except ValueError:
            return len(rank)

    items.sort(key=first)
