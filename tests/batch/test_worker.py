"""vtts batch's worker without Ray: a job gives the single command's output byte for byte and its
error message word for word, with the head loaded and the renderer built once for many jobs."""

from __future__ import annotations

import os

import pytest

from vtts.batch.jobs import parse_job
from vtts.batch.worker import JobRunner
from vtts.cli import main

os.environ.setdefault("LP_NUM_THREADS", "1")

SMALL = {"model": "cybatt", "size": "160x120"}


@pytest.fixture(scope="module")
def runner():
    return JobRunner()


def test_warm_up_loads_the_commands_and_the_drawing_pass(runner):
    from vtts.render import renderer

    seconds = runner.warm_up()
    assert seconds >= 0 and renderer._DRAWING_PASS is not None


def test_jobs_match_the_single_command_and_keep_the_renderer(tmp_path, runner):
    out = tmp_path / "out"
    jobs = [
        parse_job({"id": "a", "say": "Hi there.", **SMALL, "output": "a.mp4"}, out),
        parse_job({"id": "b", "say": "Bye.", **SMALL, "output": "b.mp4", "wav_out": "b.wav"}, out),
    ]
    builds = runner.warm.builds
    results = [runner.run(job, str(out)) for job in jobs]
    assert all(r.ok for r in results), [r.message for r in results]
    assert runner.warm.builds - builds <= 1  # one renderer for both jobs
    assert results[1].cpu_seconds > 0 and results[1].max_rss > 0
    assert [f.path for f in results[1].outputs] == ["b.mp4", "b.wav"]
    for job, name in ((jobs[0], "a.mp4"), (jobs[1], "b.mp4")):
        ref = tmp_path / f"ref-{name}"
        text = job.spec["say"]
        assert main(["say", text, "--model", "cybatt", "--size", "160x120", "-o", str(ref)]) == 0
        assert (out / name).read_bytes() == ref.read_bytes()


def test_a_bad_job_fails_with_the_commands_message(tmp_path, runner, capsys):
    job = parse_job({"id": "x", "say": "Hello <frown> you.", **SMALL, "output": "x.mp4"}, tmp_path)
    result = runner.run(job, str(tmp_path))
    assert not result.ok and not result.internal and not result.outputs
    capsys.readouterr()
    assert (
        main(["say", "Hello <frown> you.", "--model", "cybatt", "-o", str(tmp_path / "y.mp4")]) == 1
    )
    assert result.message == capsys.readouterr().err
    assert "unknown bookmark <frown>" in result.message
    assert not (tmp_path / "x.mp4").exists()


def test_stale_temporaries_of_a_dead_worker_are_removed(tmp_path, runner):
    job = parse_job({"id": "r", "render": True, **SMALL, "output": "r.png"}, tmp_path)
    stale = tmp_path / ".r.png.abcd1234.part.png"
    stale.write_bytes(b"half")
    result = runner.run(job, str(tmp_path))
    assert result.ok, result.message
    assert not stale.exists() and (tmp_path / "r.png").is_file()


def test_a_worker_counts_on_its_share_of_the_cores_for_recognition(monkeypatch):
    """A worker given its share of the machine's cores (``cpus``) recognizes a long recording
    in that many processes: with one, in its own alone, since a second would take another
    worker's core; without it, on every CPU the process may run on."""
    from vtts.speech import recognize as module

    monkeypatch.setattr(module, "_CPUS", None)  # as it was, whatever the test does
    options = module.RecognizerOptions()
    JobRunner(cpus=1)
    assert module.workers(options, 30.0) == 1
    JobRunner()
    assert module.workers(options, 30.0) == min(2, len(os.sched_getaffinity(0)))
    with pytest.raises(ValueError, match="at least 1"):
        module.set_cpus(0)
