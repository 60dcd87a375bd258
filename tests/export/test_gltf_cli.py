"""``vtts say … -o talk.glb`` and ``vtts play STREAM … -o talk.gltf``: the suffix chooses an
animated glTF instead of a video; bad input is a clear error that writes nothing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vtts.fap import FapStream
from vtts.fap.coding import encode

from ..in_process import vtts
from .gltf_helpers import HEAD, Decoded, problems, validate

ROOT = Path(__file__).parents[2]
JOY = ROOT / "tests" / "data" / "fap" / "xface-joy.fap"
FPS = 25


def test_say_writes_a_glb_and_the_speech_beside_it_when_asked(tmp_path):
    glb, wav, fap = tmp_path / "talk.glb", tmp_path / "talk.wav", tmp_path / "talk.fap"
    r = vtts("say", "Hello <smile> there, <blink> bye.", "--model", str(HEAD), "-o", str(glb),
             "--wav-out", str(wav), "--fap-out", str(fap), "--fps", str(FPS))  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"wrote {glb}, {fap}, {wav}: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["talk.fap", "talk.glb", "talk.wav"]
    assert problems(validate(glb)) == []
    decoded = Decoded(glb)
    info = decoded.doc.asset.extras["vtts"]
    frames = info["frames"]
    seconds = float(r.stdout.split(": ")[1].split(" s,")[0])
    assert info["fps"] == FPS and abs(frames / FPS - seconds) <= 1 / FPS + 1e-9
    assert decoded.times()[-1] == np.float32((frames - 1) / FPS)
    # the lips and the smile move: some morph weight changes during the utterance
    face = decoded.node_named("FACE_MESH")
    weights = np.array([decoded.channels(f)[(face, "weights")] for f in range(frames)])
    assert np.ptp(weights, axis=0).max() > 0.5


def test_say_gltf_with_png_frames_and_two_heads(tmp_path):
    out, pngs = tmp_path / "two.gltf", tmp_path / "frames"
    r = vtts("say", "Hi.", "--model", str(HEAD), "--model", str(HEAD), "-o", str(out),
             "--png-dir", str(pngs), "--size", "160x120", "--quiet")  # fmt: skip
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text(encoding="utf-8"))
    assert doc["asset"]["extras"]["vtts"]["heads"] == ["head", "head-2"]
    assert doc["cameras"][0]["extras"]["vtts"]["size"] == [160, 120]
    n = doc["asset"]["extras"]["vtts"]["frames"]
    assert len(list(pngs.glob("*.png"))) == n
    assert problems(validate(out)) == []


def test_play_writes_the_streams_animation(tmp_path):
    out = tmp_path / "joy.glb"
    r = vtts("play", str(JOY), "--model", "cybatt", "--model", str(HEAD), "-o", str(out),
             "--fps", str(FPS))  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"wrote {out}: ")
    frames = int(r.stdout.split(": ")[1].split()[0])
    decoded = Decoded(out)
    assert decoded.doc.asset.extras["vtts"] == {
        "fps": FPS, "frames": frames, "duration": frames / FPS, "heads": ["cybatt", "head"],
        "size": [352, 288],
    }  # fmt: skip
    assert len(decoded.times()) == frames
    assert problems(validate(out)) == []


def test_play_moves_the_heads_by_the_streams_translation(tmp_path):
    import shutil

    from vtts.export import placement
    from vtts.face import load_model

    # the test head with enough feature points for its FAPUs (ES, to move it by)
    wrl = tmp_path / "head.wrl"
    shutil.copy(HEAD, wrl)
    points = {"3.1": 21, "3.3": 22, "3.5": 21, "3.6": 54, "9.15": 6, "2.2": 40, "8.3": 88,
              "8.4": 89}  # fmt: skip
    text = HEAD.with_suffix(".adt").read_text(encoding="utf-8").split("#FeaturePoints")[0]
    wrl.with_suffix(".adt").write_text(
        text + "#FeaturePoints\n" + "\n".join(f"{p} FACE_MESH {v}" for p, v in points.items())
        + "\n", encoding="utf-8",
    )  # fmt: skip
    t = [[0.0, 0.0, 0.0], [200.0, 0.0, 0.0], [200.0, 100.0, -160.0]]  # ES units, steps of 4
    stream = FapStream(
        fps=FPS, name="moves", values=np.zeros((3, 68)), mask=np.zeros((3, 68)), translation=t
    )
    fbs = tmp_path / "moves.fbs"
    fbs.write_bytes(encode(stream))
    out = tmp_path / "moves.glb"
    r = vtts("play", str(fbs), "--model", str(wrl), "-o", str(out), "--fps", str(FPS))
    assert r.returncode == 0, r.stderr
    model = load_model(wrl)
    base = placement([model]).matrices[0][:3, 3]
    decoded = Decoded(out)
    root = decoded.node_named("head")
    got = np.array([decoded.channels(f)[(root, "translation")] for f in range(3)])
    np.testing.assert_allclose(got, base + np.array(t) * model.fapu.es, atol=1e-6)


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["-o", "{tmp}/x.obj"], "or an animated glTF (.glb, .gltf), not .obj"),
        (["-o", "{tmp}/x.glb", "--camera", "400,400,176,144", "--viewpoint", "V"],
         "a camera or a viewpoint"),
        (["-o", "{tmp}/x.glb", "--size", "5x5"], "image size must be within 16"),
        (["-o", "{tmp}/x.glb", "--layout", "circle"], "invalid choice: 'circle'"),
    ],
)  # fmt: skip
def test_bad_input_is_a_clear_error_and_writes_nothing(tmp_path, args, fragment):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    for cmd in (["say", "Hi."], ["play", str(JOY)]):
        r = vtts(*cmd, "--model", str(HEAD), *argv)
        assert r.returncode != 0 and fragment in r.stderr, r.stderr
        assert "Traceback" not in r.stderr
        assert list(tmp_path.iterdir()) == []


def test_a_glb_may_not_replace_an_input(tmp_path):
    stream = tmp_path / "s.glb"
    stream.write_bytes(JOY.read_bytes())
    r = vtts("play", str(stream), "--model", str(HEAD), "-o", str(stream))
    assert r.returncode == 1 and "this output is also an input" in r.stderr
    assert stream.read_bytes() == JOY.read_bytes()


def test_the_cli_knows_the_exports_suffixes():
    from vtts.api.options import GLTF_SUFFIXES
    from vtts.export import GLTF_SUFFIXES as EXPORTED

    assert GLTF_SUFFIXES == EXPORTED
