"""The vtts command: output format, exit codes, and no traceback for bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from vtts.cli import main

DATA = Path(__file__).parent / "data"
SAMPLE = Path(__file__).parents[1] / "samples" / "candide3.wrl"


def run(*args: str) -> subprocess.CompletedProcess:
    """Run the installed console script the way a user does."""
    exe = Path(sys.executable).with_name("vtts")
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=60)


def test_check_ok_lines_and_exit_zero(capsys):
    good = sorted((DATA / "vrml97" / "good").glob("*.wrl"))
    assert main(["check", *map(str, good), str(SAMPLE)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == len(good) + 1
    assert out[-1] == f"OK {SAMPLE} (7 nodes, 184 triangles)"
    assert all(line.startswith("OK ") for line in out)


def test_check_reports_file_line_col_and_exits_one(capsys):
    bad = DATA / "vrml97" / "bad" / "unrecognized-node.wrl"
    assert main(["check", str(SAMPLE), str(bad)]) == 1
    captured = capsys.readouterr()
    assert captured.out.startswith(f"OK {SAMPLE}")
    assert captured.err.startswith(f"{bad}:2:1: error: unknown node type 'UnrecognizedNode'")


def test_check_lenient_warns_and_passes(capsys):
    bad = DATA / "vrml97" / "bad" / "unrecognized-node.wrl"
    assert main(["check", "--lenient", str(bad)]) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == f"OK {bad} (1 node, 0 triangles)"
    assert f"{bad}:2:1: warning: unknown node type" in captured.err


@pytest.mark.parametrize(
    "content, fragment",
    [
        ("#VRML V1.0 ascii\n", ":1:1: error: VRML 1.0 is not supported"),
        ("#VRML V2.0 utf8\nGroup { children [ }\n", ":2:20: error: unexpected '}'"),
        (b'#VRML V2.0 utf8\nWorldInfo { title "\xfe" }', ":2:20: error: invalid UTF-8"),
    ],
)
def test_bad_input_never_shows_a_traceback(tmp_path, content, fragment):
    f = tmp_path / "bad.wrl"
    if isinstance(content, bytes):
        f.write_bytes(content)
    else:
        f.write_text(content)
    r = run("check", str(f))
    assert r.returncode == 1
    assert fragment in r.stderr
    assert "Traceback" not in r.stderr


def test_missing_file_and_unknown_type(tmp_path):
    r = run("check", str(tmp_path / "nope.wrl"), str(tmp_path / "x.obj"))
    assert r.returncode == 1
    assert "nope.wrl: error: no such file" in r.stderr
    assert "unknown file type '.obj'" in r.stderr
    assert "Traceback" not in r.stderr


def test_info_prints_the_tree(capsys):
    assert main(["info", str(SAMPLE)]) == 0
    out = capsys.readouterr().out
    assert "DEF HEAD Transform" in out
    assert "DEF FACE_MESH IndexedFaceSet: 113 vertices, 184 faces, 184 triangles" in out


def test_info_bad_file(tmp_path, capsys):
    f = tmp_path / "x.wrl"
    f.write_text("#VRML V2.0 utf8\nFoo {}\n")
    assert main(["info", str(f)]) == 1
    assert f"{f}:2:1: error: unknown node type 'Foo'" in capsys.readouterr().err


def test_the_command_flushes_its_output_before_leaving(tmp_path):
    """``vtts`` leaves through ``os._exit`` (no interpreter teardown): everything it printed
    through a pipe still arrives, and the exit code is main()'s."""
    good = sorted((DATA / "vrml97" / "good").glob("*.wrl"))
    r = run("check", *map(str, good))
    assert r.returncode == 0
    assert r.stdout.count("\n") == len(good) > 10
    with_main = subprocess.run(
        [sys.executable, "-c", "import sys; from vtts.cli import main; "
         f"sys.exit(main(['check', *{[str(g) for g in good]!r}]))"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.stdout == with_main.stdout
    bad = run("check", str(tmp_path / "missing.wrl"))
    assert bad.returncode == 1 and "missing.wrl" in bad.stderr and "Traceback" not in bad.stderr


def test_usage_errors_exit_two():
    r = run("check")
    assert r.returncode == 2 and "usage: vtts check" in r.stderr


def test_outputs_get_ordinary_permissions(tmp_path):
    """Atomic writes go through a private temp file; the result is readable like any output."""
    import os
    import stat

    from vtts.atomic import current_umask, write_text

    out = tmp_path / "x.txt"
    write_text(out, "hi")
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o666 & ~current_umask()


def test_a_warning_without_a_file_is_told_of_the_input_given(capsys):
    """``reported_warnings(file=...)`` names the input where the library could not (the fit sees
    a photo's pixels, not its file); a warning that names its own file keeps it."""
    import warnings

    from vtts.errors import VttsWarning
    from vtts.messages import reported_warnings

    with reported_warnings(file="me.jpg"):
        warnings.warn(VttsWarning("the photo shows glasses"), stacklevel=1)
        warnings.warn(VttsWarning("odd node", file="x.wrl", line=3, column=1), stacklevel=1)
    err = capsys.readouterr().err.splitlines()
    assert err == ["me.jpg: warning: the photo shows glasses", "x.wrl:3:1: warning: odd node"]
