"""vtts batch's jobs and manifest, without Ray: a job line is the command's options dataclass,
checked as the command checks it; bad lines are reported with their line numbers; the manifest
says which jobs are finished."""

from __future__ import annotations

import json
import time

import pytest

from vtts import PlayOptions, RenderOptions, SayOptions
from vtts.api.options import OUTPUT_OPTIONS
from vtts.batch.jobs import JobError, as_jobs, parse_job, read_jobs
from vtts.batch.manifest import (
    Manifest,
    OutputFile,
    output_files,
    read_failures,
    write_failures,
)
from vtts.cli import main


def test_a_job_is_the_command_line_with_its_outputs_under_the_folder(tmp_path):
    spec = {
        "id": "q17",
        "say": "-Hello <smile>",  # a text starting with '-' stays the text
        "model": ["cybatt", "lotta"],
        "size": "160x120",
        "no-autonomous": True,
        "fap_out": "fap/q17.fap",
        "output": "q17.mp4",
    }
    job = parse_job(spec, tmp_path)
    assert job.id == "q17" and job.command == "say"
    assert job.outputs == ("fap/q17.fap", "q17.mp4")
    options = job.options
    assert isinstance(options, SayOptions)
    assert options.text == "-Hello <smile>"
    assert options.model == ["cybatt", "lotta"]
    assert options.size == "160x120" and options.no_autonomous and not options.progress
    assert options.output == str(tmp_path / "q17.mp4")
    assert options.fap_out == str(tmp_path / "fap" / "q17.fap")


def test_every_out_option_is_an_output_under_the_folder(tmp_path):
    job = parse_job(
        {"say": "Hi.", "model": "cybatt", "timings_out": "t/a.tsv", "curves-out": "a.json"},
        tmp_path,
    )
    assert job.outputs == ("t/a.tsv", "a.json")
    assert job.options.timings_out == str(tmp_path / "t/a.tsv")
    assert job.options.curves_out == str(tmp_path / "a.json")


@pytest.mark.parametrize("dest", OUTPUT_OPTIONS)
def test_the_commands_outputs_are_a_jobs_outputs(tmp_path, dest):
    """Every option the commands check as an output (``vtts.api.options.OUTPUT_OPTIONS``) is
    kept in the batch's folder."""
    name = f"o/{dest}.mp4" if dest == "output" else f"o/{dest}"
    job = parse_job({"say": "Hi.", "model": "cybatt", dest: name}, tmp_path)
    assert job.outputs == (name,)
    assert getattr(job.options, dest) == str(tmp_path / name)


def test_render_and_play_jobs(tmp_path):
    render = parse_job(
        {"render": True, "model": "lotta", "expression": "joy", "output": "a.png"}, tmp_path
    )
    assert render.id == "a.png"  # no id: the first output names the job
    assert isinstance(render.options, RenderOptions) and render.options.expression == ["joy"]
    play = parse_job({"id": "p", "play": "x.fap", "model": "cybatt", "png_dir": "frames"}, tmp_path)
    assert isinstance(play.options, PlayOptions)
    assert play.options.stream == "x.fap" and play.outputs == ("frames/",)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ([1, 2], "a job is a JSON object"),
        ({"say": "x", "play": "y", "output": "a.mp4"}, "one of 'say', 'play' or 'render'"),
        ({"output": "a.mp4"}, "one of 'say', 'play' or 'render'"),
        ({"say": "x"}, "the job writes nothing"),
        ({"say": "x", "output": "/tmp/a.mp4"}, "give a relative path"),
        ({"say": "x", "output": "../a.mp4"}, "leaves the batch's folder"),
        ({"say": "x", "output": "a.mp4", "sise": "1x1"}, "vtts say has no option 'sise'"),
        ({"say": "x", "output": "./manifest.jsonl"}, "manifest.jsonl is the batch's own"),
        ({"say": "x", "output": "a.mp4", "help": True}, "has no option 'help'"),
        ({"say": "x", "output": "a.mp4", "seed": -1}, "vtts say: --seed -1 must be within"),
        ({"say": "x", "output": "a.mp4", "seed": "one"}, "'seed' takes a whole number"),
        ({"say": "x", "output": "a.mp4", "layout": "ring"}, "--layout must be one of row, room"),
        ({"say": "x", "output": "a.png"}, "a.png: -o writes a video"),
        ({"say": "x", "text": "y", "model": "cybatt", "output": "a.mp4"}, "give the text once"),
        ({"say": "x", "output": "a.mp4", "voice": ["a", "b"]}, "'voice' takes one value"),
        ({"say": "x", "output": "a.mp4", "no_autonomous": "yes"}, "is a flag: give true"),
        ({"say": "x", "output": "a.mp4", "model": {"a": 1}}, "takes a string or a number"),
        ({"render": True, "output": "a.png"}, "vtts render: no model"),
        ({"render": "yes", "model": "cybatt", "output": "a.png"}, "'render' takes true"),
        ({"play": 3, "model": "cybatt", "output": "a.mp4"}, "'play' takes the .fap"),
        ({"id": "", "say": "x", "output": "a.mp4"}, "'id' is a string of 1 to"),
        ({"say": "x", "output": "a.mp4", "file": "a\x00b"}, "'file' holds a NUL character"),
        ({"say": "a\x00", "output": "a.mp4"}, "'say' holds a NUL character"),
    ],
)
def test_bad_jobs_say_what_is_wrong(tmp_path, spec, message):
    with pytest.raises(JobError) as e:
        parse_job(spec, tmp_path)
    assert message in e.value.message


def _jobs_file(tmp_path, lines):
    path = tmp_path / "jobs.jsonl"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_a_jobs_file_reports_each_bad_line_and_keeps_the_good_ones(tmp_path):
    ok = {"id": "a", "say": "Hi.", "model": "cybatt", "output": "a.mp4"}
    path = _jobs_file(
        tmp_path,
        [
            json.dumps(ok),
            "",  # blank lines are skipped
            '{"id": "b", "say": "Hi.", ',
            json.dumps({**ok, "output": "b.mp4"}),  # the same id again
            json.dumps({**ok, "id": "c"}),  # the same output again
            json.dumps({**ok, "id": "d", "output": "d.mp4", "fps": "fast"}),
            json.dumps({**ok, "id": "e", "output": "e.mp4"}),
            "[" * 100_000,  # deeper than the JSON reader's recursion
        ],
    )
    checked = read_jobs(path, tmp_path / "out")
    assert [j.id for j in checked.jobs] == ["a", "e"]
    assert [j.line for j in checked.jobs] == [1, 7]
    found = [(e.line, e.message) for e in checked.errors]
    assert [line for line, _ in found] == [3, 4, 5, 6, 8]
    assert found[4][1] == "not a job: its JSON is nested too deeply"
    assert found[0][1].startswith("not JSON")
    assert checked.errors[0].column is not None
    assert found[1][1] == "id 'a' is also the id on line 1"
    assert found[2][1] == "'a.mp4' is also written by line 1"
    assert found[3][1] == "'fps' takes a number, got \"fast\""
    assert checked.errors[0].location().startswith(f"{path}:3:")


def test_a_job_may_not_write_the_jobs_file(tmp_path):
    path = _jobs_file(tmp_path, [json.dumps({"say": "x", "model": "cybatt", "wav_out": "j.wav"})])
    path = path.rename(tmp_path / "j.wav")
    checked = read_jobs(path, tmp_path)
    assert (
        not checked.jobs and checked.errors[0].message == "an output of this job is the jobs file"
    )


def test_library_jobs_are_checked_as_lines_are(tmp_path):
    checked = as_jobs(
        [{"say": "Hi.", "model": "cybatt", "output": "a.mp4"}, {"say": "Hi."}], tmp_path
    )
    assert [j.id for j in checked.jobs] == ["a.mp4"]
    assert [e.line for e in checked.errors] == [2]


def test_dry_run_reports_bad_lines_with_their_numbers(tmp_path, capsys):
    ok = {"id": "a", "say": "Hi.", "model": "cybatt", "output": "a.mp4"}
    path = _jobs_file(tmp_path, [json.dumps(ok), "{oops"])
    assert main(["batch", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 1
    out, err = capsys.readouterr()
    assert f"{path}:2:2: error: not JSON" in err
    assert "1 valid job, 1 bad" in out
    assert not (tmp_path / "out").exists()  # a dry run writes nothing
    path.write_text(json.dumps(ok) + "\n")
    assert main(["batch", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 0


def test_dry_run_checks_heads_inputs_and_bookmarks_without_rendering(tmp_path, capsys):
    ok = {"id": "a", "say": "Hi <smile>.", "model": "cybatt", "output": "a.mp4"}
    lines = [
        ok,
        {**ok, "id": "b", "say": "Hello <frown> you.", "output": "b.mp4"},
        {**ok, "id": "c", "model": "nobody", "output": "c.mp4"},
        {"id": "d", "play": str(tmp_path / "none.fap"), "model": "cybatt", "output": "d.mp4"},
    ]
    path = _jobs_file(tmp_path, [json.dumps(x) for x in lines])
    assert main(["batch", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 1
    out, err = capsys.readouterr()
    assert "1 valid job, 3 bad" in out
    errors = err.splitlines()
    assert errors[0].startswith(f"{path}:2: error: vtts say: column 7: unknown bookmark <frown>")
    assert errors[1].startswith(f"{path}:3: error: vtts say: no model 'nobody'")
    assert errors[2] == f"{path}:4: error: vtts play: {tmp_path / 'none.fap'}: no such file"


DRY = {"model": "cybatt"}


@pytest.mark.parametrize(
    "job, message",
    [
        # each passed the dry run, then failed at once (the first as an internal error)
        ({"say": "Hi.", "size": "--", "output": "a.mp4"}, "--size takes WIDTHxHEIGHT"),
        ({"render": True, "size": "--", "output": "a.png"}, "--size takes WIDTHxHEIGHT"),
        ({"say": "Hi.", "size": "100000x100000", "output": "a.mp4"}, "image size must be within"),
        ({"play": "x.fap", "size": "4000x4000", "output": "a.mp4"}, "more than the limit of"),
        ({"say": "Hi.", "size": "8x8", "output": "a.mp4"}, "image size must be within 16"),
        ({"say": "Hi.", "output": "a.mp4", "wav_out": "a.mp4"}, "also written by this job's other"),
        ({"say": "Hi.", "output": "a.mp4", "fap_out": "a.mp4"}, "also written by this job's other"),
        ({"render": True, "fap": "3=1e300", "output": "a.png"}, "1e300 must be within"),
        ({"render": True, "viseme": "3=2", "output": "a.png"}, "must be within"),
        ({"say": "Hi.", "fps": 1e308, "output": "a.mp4"}, "--fps must be within"),
    ],
)
def test_dry_run_runs_the_checks_of_a_run(tmp_path, capsys, job, message):
    path = _jobs_file(tmp_path, [json.dumps({**DRY, **job})])
    assert main(["batch", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 1
    out, err = capsys.readouterr()
    assert "0 valid jobs, 1 bad" in out
    assert message in err and "Traceback" not in err and "internal" not in err


def test_dry_run_passes_sizes_a_renderer_draws(tmp_path, capsys):
    jobs = [{**DRY, "say": "Hi.", "size": size, "output": f"{size}.mp4"}
            for size in ("16x16", "3840x2160", "4096x2025")]  # fmt: skip
    path = _jobs_file(tmp_path, [json.dumps(j) for j in jobs])
    assert main(["batch", str(path), "--out", str(tmp_path / "out"), "--dry-run"]) == 0


def test_the_manifest_knows_finished_jobs(tmp_path):
    job = parse_job({"id": "a", "say": "Hi.", "model": "cybatt", "output": "x/a.mp4"}, tmp_path)
    (tmp_path / "x").mkdir()
    (tmp_path / "x/a.mp4").write_bytes(b"video")
    manifest = Manifest(tmp_path)
    assert not manifest.finished(job)
    files = output_files(tmp_path, job)
    assert files == [OutputFile("x/a.mp4", 5, files[0].sha256)]
    manifest.record(job, files, seconds=1.0)
    # a cut-off last line (a batch stopped while writing) is skipped
    with open(tmp_path / "manifest.jsonl", "a") as f:
        f.write('{"id": "b", "dig')
    again = Manifest(tmp_path)
    assert again.finished(job) and "b" not in again.entries
    (tmp_path / "x/a.mp4").write_bytes(b"vide0")  # same size, other bytes
    assert not Manifest(tmp_path).finished(job)
    (tmp_path / "x/a.mp4").write_bytes(b"video")
    changed = parse_job({"id": "a", "say": "Ho.", "model": "cybatt", "output": "x/a.mp4"}, tmp_path)
    assert not Manifest(tmp_path).finished(changed)  # the job's line changed: run it again
    (tmp_path / "x/a.mp4").unlink()
    assert not Manifest(tmp_path).finished(job)


def test_folder_outputs_count_every_file(tmp_path):
    job = parse_job({"id": "p", "play": "x.fap", "model": "cybatt", "png_dir": "f"}, tmp_path)
    with pytest.raises(FileNotFoundError):
        output_files(tmp_path, job)
    (tmp_path / "f").mkdir()
    for i in range(2):
        (tmp_path / f"f/frame_{i:06d}.png").write_bytes(b"png" * (i + 1))
    files = output_files(tmp_path, job)
    assert [f.path for f in files] == ["f/frame_000000.png", "f/frame_000001.png"]
    m = Manifest(tmp_path)
    m.record(job, files)
    assert Manifest(tmp_path).finished(job)
    (tmp_path / "f/frame_000001.png").unlink()
    assert not Manifest(tmp_path).finished(job)


def test_failures_file_is_replaced_and_removed_when_none(tmp_path):
    path = write_failures(tmp_path, [{"id": "a", "error": "error: x"}])
    assert json.loads(path.read_text()) == {"id": "a", "error": "error: x"}
    assert read_failures(tmp_path) == {"a": {"id": "a", "error": "error: x"}}
    stamp = path.stat().st_mtime_ns
    time.sleep(0.01)
    write_failures(tmp_path, [{"id": "a", "error": "error: x"}])
    assert path.stat().st_mtime_ns == stamp  # the same failures: the file is left as it was
    write_failures(tmp_path, [])
    assert not path.exists()


def test_a_jobs_file_larger_than_the_cap_is_refused(tmp_path, monkeypatch):
    path = _jobs_file(tmp_path, [json.dumps({"say": "Hi.", "model": "cybatt", "output": "a.mp4"})])
    monkeypatch.setattr("vtts.limits.MAX_JOBS_BYTES", 16)
    with pytest.raises(JobError, match="larger than the limit"):
        read_jobs(path, tmp_path)
    with pytest.raises(JobError, match="cannot read the jobs"):
        read_jobs(tmp_path / "none.jsonl", tmp_path)


def test_a_job_may_not_write_the_jobs_file_through_a_link(tmp_path):
    # a link that stays inside --out (the jobs file's own folder here) passes the link rule
    (tmp_path / "here").symlink_to(tmp_path)
    path = _jobs_file(tmp_path, [json.dumps({"say": "x", "model": "cybatt", "output": "a.mp4"})])
    path.write_text(json.dumps({"say": "x", "model": "cybatt", "wav_out": f"here/{path.name}"}))
    checked = read_jobs(path, tmp_path)
    assert [e.message for e in checked.errors] == ["an output of this job is the jobs file"]
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "here").symlink_to(tmp_path)
    checked = read_jobs(path, tmp_path / "out")  # and one that leaves --out is refused as such
    assert [e.message for e in checked.errors] == [
        f"'wav_out': 'here/{path.name}' leads out of the batch's folder (--out) through a link, "
        f"to {path}"
    ]


def test_reading_jobs_resolves_no_path_per_job(tmp_path, monkeypatch):
    """A jobs file of 400k lines took minutes to read: each job's outputs and the jobs file
    itself were resolved component by component (realpath) to tell whether a job writes the
    jobs file. An output that does not exist yet cannot be it: one stat tells."""
    import os.path

    lines = [
        json.dumps({"say": f"Hi {i}.", "model": "cybatt", "output": f"c{i}.mp4"})
        for i in range(200)
    ]
    path = _jobs_file(tmp_path, lines)
    calls = []
    real = os.path.realpath
    monkeypatch.setattr(os.path, "realpath", lambda *a, **k: calls.append(a) or real(*a, **k))
    checked = read_jobs(path, tmp_path / "out")
    assert len(checked.jobs) == 200 and not checked.errors
    assert len(calls) < 10, len(calls)  # was 2 a job


def test_a_jobs_file_of_more_jobs_than_the_limit_is_refused(tmp_path, monkeypatch):
    job = {"say": "Hi.", "model": "cybatt"}
    lines = [json.dumps({**job, "output": f"{i}.mp4"}) for i in range(4)]
    path = _jobs_file(tmp_path, [*lines, "", "  "])  # blank lines are no jobs
    monkeypatch.setattr("vtts.limits.MAX_JOBS", 4)
    assert len(read_jobs(path, tmp_path).jobs) == 4
    path.write_text("\n".join([*lines, json.dumps({**job, "output": "5.mp4"})]))
    with pytest.raises(JobError, match="5 jobs in one file, more than the limit of 4: split"):
        read_jobs(path, tmp_path)
