"""The ``vtts`` command pauses Python's cyclic garbage collector while it starts
(``vtts.cli.run``) and resumes it: ``say`` and ``play`` after their first frame, every other
command before it starts."""

from __future__ import annotations

import gc
from pathlib import Path

import pytest

from vtts.cli import _main as cli

VRML = Path(__file__).resolve().parent / "data" / "models" / "head.wrl"


@pytest.fixture
def paused(monkeypatch):
    """As ``run`` leaves it: the collector off and the pause noted; restored afterwards."""
    gc.disable()
    monkeypatch.setattr(cli, "_GC_PAUSED", True)
    try:
        yield
    finally:
        gc.unfreeze()  # the objects run would freeze are this test process's
        gc.enable()


def _watch(monkeypatch) -> list[tuple[str, bool]]:
    seen: list[tuple[str, bool]] = []
    check_io = cli._check_io

    def watched(args):
        seen.append(("start", gc.isenabled()))
        return check_io(args)

    monkeypatch.setattr(cli, "_check_io", watched)
    return seen


def test_say_resumes_the_collector_after_its_first_frame(paused, monkeypatch, tmp_path):
    from vtts.render import PngSequenceWriter

    seen = _watch(monkeypatch)
    write = PngSequenceWriter.write

    def watched(self, frame):
        seen.append(("frame", gc.isenabled()))
        return write(self, frame)

    monkeypatch.setattr(PngSequenceWriter, "write", watched)
    argv = ["say", "Hello there", "--model", "cybatt", "--png-dir", str(tmp_path), "--quiet"]
    assert cli.main(argv) == 0
    frames = [on for kind, on in seen if kind == "frame"]
    assert seen[0] == ("start", False) and len(frames) > 5
    assert frames[0] is False and all(frames[1:])  # on again once the first frame is out
    assert gc.isenabled() and not cli._GC_PAUSED and gc.get_freeze_count() > 0


def test_other_commands_resume_it_before_they_start(paused, monkeypatch, capsys):
    seen = _watch(monkeypatch)
    assert cli.main(["check", str(VRML)]) == 0
    assert seen == [("start", True)] and not cli._GC_PAUSED


def test_main_alone_leaves_the_collector_as_it_was(monkeypatch, tmp_path):
    seen = _watch(monkeypatch)
    assert gc.isenabled() and not cli._GC_PAUSED
    argv = ["say", "Hi", "--model", "cybatt", "--png-dir", str(tmp_path), "--quiet"]
    assert cli.main(argv) == 0
    assert seen == [("start", True)] and gc.isenabled() and gc.get_freeze_count() == 0
