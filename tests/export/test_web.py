"""The web player's folder (vtts.export.web, vtts say/play --web): what it holds, the vendored
three.js it ships, how it replaces a previous folder and refuses to replace anything else."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from vtts.export.web import (
    AUDIO_NAME,
    GLB_NAME,
    PLAYER_DIR,
    WebError,
    check_web_folder,
    write_web,
)
from vtts.face.miap import N_PARAMS
from vtts.render import probe_media, write_wav

from ..in_process import vtts

ROOT = Path(__file__).parents[2]
DATA = Path(__file__).parents[1] / "data"
HEAD = DATA / "models" / "head.wrl"
JOY = DATA / "fap" / "xface-joy.fap"


def page_config(folder: Path) -> dict:
    text = (folder / "index.html").read_text(encoding="utf-8")
    m = re.search(r'<script type="application/json" id="vtts-config">(.*?)</script>', text, re.S)
    assert m, "index.html carries the player's settings"
    return json.loads(m[1])


@pytest.fixture(scope="module")
def head():
    from vtts.face import load_model

    return load_model(HEAD)


@pytest.fixture
def tone(tmp_path) -> Path:
    rate = 16000
    t = np.arange(int(rate * 1.25)) / rate
    wav = tmp_path / "tone.wav"
    write_wav(wav, (0.2 * np.sin(2 * np.pi * 220 * t)).astype(np.float32), rate)
    return wav


def leftovers(parent: Path, keep: set[str]) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if p.name not in keep)


def test_folder_holds_page_glb_audio_player_and_three(tmp_path, head, tone):
    params = [np.zeros((30, N_PARAMS))]
    out = write_web(tmp_path / "web", [head], params, 30.0, audio=tone, title="a <test>")
    assert out == tmp_path / "web"
    names = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert {"index.html", "player.js", GLB_NAME, AUDIO_NAME} <= names
    for shipped in (PLAYER_DIR / "vendor").rglob("*"):
        if shipped.is_file():
            rel = shipped.relative_to(PLAYER_DIR).as_posix()
            assert (out / rel).read_bytes() == shipped.read_bytes(), rel
    assert (out / GLB_NAME).read_bytes()[:4] == b"glTF"
    config = page_config(out)
    assert config["glb"] == GLB_NAME and config["audio"] == AUDIO_NAME
    assert config["fps"] == 30.0 and config["frames"] == 30
    assert config["heads"] == [head.name]
    assert config["duration"] == pytest.approx(1.25, abs=1e-6)  # the audio outlasts the frames
    info = probe_media(out / AUDIO_NAME)
    assert info.duration_audio == pytest.approx(1.25, abs=0.03)
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "<title>a &lt;test&gt;</title>" in page
    assert "http://" not in page and "https://" not in page  # nothing from the network
    assert leftovers(tmp_path, {"web", "tone.wav"}) == []


def test_a_model_given_twice_is_named_as_the_glb_names_it(tmp_path, head):
    import json

    params = [np.zeros((6, N_PARAMS))] * 2
    out = write_web(tmp_path / "web", [head, head], params, 24.0)
    assert page_config(out)["heads"] == [head.name, f"{head.name}-2"]
    # the .glb's JSON chunk: 12-byte header, then length and type of the chunk
    data = (out / GLB_NAME).read_bytes()
    length = int.from_bytes(data[12:16], "little")
    doc = json.loads(data[20 : 20 + length])
    assert doc["asset"]["extras"]["vtts"]["heads"] == page_config(out)["heads"]


def test_without_audio_there_is_none(tmp_path, head):
    out = write_web(tmp_path / "web", [head], [np.zeros((12, N_PARAMS))], 24.0)
    assert not (out / AUDIO_NAME).exists()
    config = page_config(out)
    assert config["audio"] is None
    assert config["duration"] == pytest.approx(12 / 24.0)


def imports_of(path: Path) -> list[str]:
    """The specifiers of an ES module's import statements (not those shown in comments)."""
    text = path.read_text(encoding="utf-8")
    return re.findall(r"^(?:import|\}) [^'\n]*from '([^']+)';?\s*$", text, re.M) + re.findall(
        r"^import '([^']+)';?\s*$", text, re.M
    )


def test_every_module_the_player_imports_is_shipped():
    """The import map of index.html and the vendored files resolve every import: a re-vendoring
    that misses a file fails here, not in a user's browser."""
    page = (PLAYER_DIR / "index.html").read_text(encoding="utf-8")
    mapping = json.loads(re.search(r'<script type="importmap">(.*?)</script>', page, re.S)[1])
    imports = mapping["imports"]

    def resolve(spec: str, importer: Path) -> Path:
        if spec.startswith("."):
            return (importer.parent / spec).resolve()
        if spec in imports:
            return (PLAYER_DIR / imports[spec]).resolve()
        prefix = next((p for p in imports if p.endswith("/") and spec.startswith(p)), None)
        assert prefix is not None, f"{importer.name} imports {spec!r}, which nothing maps"
        return (PLAYER_DIR / imports[prefix] / spec[len(prefix) :]).resolve()

    seen: set[Path] = set()
    todo = [PLAYER_DIR / "player.js"]
    while todo:
        module = todo.pop()
        if module in seen:
            continue
        seen.add(module)
        for spec in imports_of(module):
            target = resolve(spec, module)
            assert target.is_file(), f"{module.name} imports {spec}: {target} is not shipped"
            todo.append(target)
        if module.name == "three.module.min.js":
            for spec in re.findall(r'from"(\./[^"]+)"', module.read_text(encoding="utf-8")):
                todo.append((module.parent / spec).resolve())
    names = {p.name for p in seen}
    assert {"GLTFLoader.js", "OrbitControls.js", "three.core.min.js"} <= names
    vendor = PLAYER_DIR / "vendor"
    assert "MIT License" in (vendor / "LICENSE").read_text(encoding="utf-8")
    pinned = re.search(r"^THREE_VERSION=(\S+)$", (ROOT / "scripts" / "vendor_three.sh").read_text(),
                       re.M)  # fmt: skip
    assert (vendor / "VERSION").read_text().strip() == pinned[1]
    # the build's first statement is its REVISION constant (minified: const t="182")
    head = (vendor / "three.core.min.js").read_text(encoding="utf-8")[:300]
    assert re.search(r'const \w+="([0-9]+)"', head)[1] == pinned[1].split(".")[1]


def test_a_previous_web_folder_is_replaced_whole(tmp_path, head, tone):
    out = tmp_path / "web"
    write_web(out, [head], [np.zeros((10, N_PARAMS))], 30.0, audio=tone)
    assert (out / AUDIO_NAME).is_file()
    write_web(out, [head], [np.zeros((20, N_PARAMS))], 30.0)
    assert not (out / AUDIO_NAME).exists()  # nothing of the old folder is left over
    assert page_config(out)["frames"] == 20
    assert leftovers(tmp_path, {"web", "tone.wav"}) == []


def test_an_empty_folder_is_used(tmp_path, head):
    (tmp_path / "web").mkdir()
    write_web(tmp_path / "web", [head], [np.zeros((3, N_PARAMS))], 30.0)
    assert (tmp_path / "web" / "index.html").is_file()


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda p: p.write_text("x"), "is a file"),
        (lambda p: (p.mkdir(), (p / "notes.txt").write_text("mine")), "not a vtts web folder"),
        (
            lambda p: (p.mkdir(), (p / "index.html").write_text("<html>my page</html>")),
            "not a vtts web folder",
        ),  # fmt: skip
        (lambda p: p.symlink_to(p.parent), "link"),
    ],
)
def test_what_is_not_a_web_folder_is_refused_untouched(tmp_path, make, words):
    target = tmp_path / "web"
    make(target)
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    with pytest.raises(WebError, match=words) as e:
        check_web_folder(target)
    assert e.value.file == str(target)
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before


def test_a_web_folder_with_the_users_files_in_it_is_refused(tmp_path, head):
    out = write_web(tmp_path / "web", [head], [np.zeros((3, N_PARAMS))], 30.0)
    (out / "my-notes.txt").write_text("mine")
    with pytest.raises(WebError, match="my-notes.txt"):
        write_web(out, [head], [np.zeros((3, N_PARAMS))], 30.0)
    assert (out / "my-notes.txt").read_text() == "mine"


def test_a_failure_leaves_nothing(tmp_path, head):
    bad = tmp_path / "bad.wav"
    bad.write_bytes(b"RIFF not really")
    with pytest.raises(WebError, match="cannot read the audio") as e:
        write_web(tmp_path / "web", [head], [np.zeros((3, N_PARAMS))], 30.0, audio=bad)
    assert e.value.file == str(bad)
    assert leftovers(tmp_path, {"bad.wav"}) == []


def test_say_web_writes_the_folder_with_speech(tmp_path):
    out = tmp_path / "hello"
    r = vtts("say", "Hello <smile>", "--model", str(HEAD), "--web", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    config = page_config(out)
    assert config["audio"] == AUDIO_NAME
    speech = probe_media(out / AUDIO_NAME).duration_audio
    assert config["duration"] == pytest.approx(max(speech, config["frames"] / 30), abs=0.05)
    assert not list(tmp_path.glob(".*"))


def test_play_web_of_a_stream_without_audio(tmp_path):
    out = tmp_path / "joy"
    r = vtts("play", str(JOY), "--model", str(HEAD), "--web", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    config = page_config(out)
    assert config["audio"] is None and not (out / AUDIO_NAME).exists()
    assert config["frames"] > 10


def test_web_into_a_foreign_folder_is_a_clear_error(tmp_path):
    (tmp_path / "site").mkdir()
    (tmp_path / "site" / "index.html").write_text("<html>mine</html>")
    r = vtts("play", str(JOY), "--model", str(HEAD), "--web", str(tmp_path / "site"))
    assert r.returncode == 1
    assert "Traceback" not in r.stderr
    assert str(tmp_path / "site") in r.stderr and "not a vtts web folder" in r.stderr
    assert (tmp_path / "site" / "index.html").read_text() == "<html>mine</html>"
