"""The wheel carries grammars/ and models/ inside the package, and code finds them there."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "build",
            "--wheel",
            "--no-isolation",
            "--outdir",
            str(out),
            str(ROOT),
        ],
        check=True,
        capture_output=True,
        timeout=300,
    )
    (whl,) = out.glob("vtts-*.whl")
    return whl


def test_wheel_contains_grammars_models_and_both_packages(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert "vtts/_data/grammars/vrml97.lark" in names
    assert any(n.startswith("vtts/_data/models/") for n in names)
    assert "vtts/vrml/standard_nodes.txt" in names
    assert "vtts/render/shaders/gbuffer.frag" in names
    assert "vtts/data/landmarks/face_detection_short_range.tflite" in names
    assert "vtts/data/landmarks/face_landmark.tflite" in names
    assert "vtts/data/landmarks/iris_landmark.tflite" in names
    assert "vtts/data/landmarks/selfie_segmentation.tflite" in names
    # adi fit: where the landmarks lie on FACE, and Candide-3 for the subdivision matrix
    assert "vtts/data/fit/face_landmarks.tsv" in names
    # the ARKit recipe table (avatars in, curves out)
    assert "vtts/data/arkit_recipes.tsv" in names
    assert "vtts/_data/models/src/candide3.wfm" in names
    # the web player (vtts say/play --web) and the three.js it ships, with three's licence
    for name in ("player.js", "head.js", "index.html", "vendor/three.module.min.js",
                 "vendor/LICENSE"):  # fmt: skip
        assert f"vtts/export/player/{name}" in names, name
    # vtts serve's page and its JavaScript client
    for name in ("index.html", "serve.js", "client.js"):
        assert f"vtts/serve/page/{name}" in names, name
    assert "adt_tools/__init__.py" in names
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    text = zipfile.ZipFile(wheel).read(entry_points).decode()
    assert "vtts = vtts.cli:run" in text and "adi = adt_tools.cli:main" in text


def test_installed_wheel_parses_without_the_checkout(wheel, tmp_path):
    target = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(target)
    code = (
        "import vtts.resources as r, vtts.vrml as v;"
        "assert '_data' in str(r.grammar_path('vrml97')), r.grammar_path('vrml97');"
        "print(v.parse('#VRML V2.0 utf8\\nGroup {}').node_count)"
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env={"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "1"
