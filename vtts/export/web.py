"""The web player: a folder that plays an utterance in any browser, offline, from a static server.

:func:`write_web` writes::

    DIR/index.html     the page (the player's settings inside it, as JSON)
    DIR/talk.glb       the heads and their animation (:func:`vtts.export.gltf.write_gltf`)
    DIR/speech.m4a     the audio as AAC, when there is audio
    DIR/player.js      the player (and head.js, the scene it shares with ``vtts serve``'s page)
    DIR/vendor/        three.js, its GLTFLoader and OrbitControls, and three's LICENSE

The player and three.js are package data (``vtts/export/player/``; ``scripts/vendor_three.sh``
re-vendors three.js at its pinned version): nothing is fetched from the network, then or later.
ES modules are not loaded from ``file://`` URLs, so the folder is served, by any static server:
``python -m http.server -d DIR``.

The files are written into a hidden folder inside ``DIR`` and moved into place when all are
complete, ``index.html`` last, so no file is ever seen half-written; ``DIR`` itself is kept (it
may be ``.``, the folder a shell is in). ``DIR/.vtts-files`` lists what was written. An existing
``DIR`` must be empty or a folder this function wrote before (its ``index.html`` carries the
player's mark, and every file in it, ``vendor/`` included, is one the player wrote): its files
are replaced. Anything else is refused before any work, so that no file of the user's is ever
deleted.
"""

from __future__ import annotations

import contextlib
import html
import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path, PurePosixPath
from string import Template

import numpy as np

from vtts.errors import ExportError

__all__ = ["AUDIO_NAME", "GLB_NAME", "PLAYER_DIR", "WebError", "check_web_folder", "write_web"]

#: Package data: the page template, the player's script and the vendored three.js.
PLAYER_DIR = Path(__file__).parent / "player"
#: File names inside a web folder.
GLB_NAME = "talk.glb"
AUDIO_NAME = "speech.m4a"
#: The mark of a folder written by :func:`write_web` (a line of its ``index.html``).
MARK = '<meta name="generator" content="vtts web player">'
#: What a web folder holds at its top: a folder holding anything else is not replaced.
FOLDER_ENTRIES = frozenset({"index.html", "player.js", "head.js", "vendor", GLB_NAME, AUDIO_NAME})
#: The list of the files :func:`write_web` wrote (POSIX paths, one a line): on the next write,
#: anything else found in the folder is the user's.
FILES_NAME = ".vtts-files"
#: The prefix of the hidden folders a write stages its files in (and the previous ones in).
STAGING_PREFIX = ".vtts-web."
#: vtts render's default background (0.32, 0.36, 0.42), as the page's CSS color.
DEFAULT_BACKGROUND = "#525c6b"


class WebError(ExportError):
    """A web folder cannot be written where asked, or its audio cannot be read."""


def check_web_folder(directory: str | os.PathLike[str]) -> None:
    """Refuse, before anything is computed, a ``directory`` that :func:`write_web` must not
    write into: a file, a link, or a non-empty folder that is not a previous web folder of vtts
    or holds anything vtts did not write there (a file added to ``vendor/`` too). Raises
    :class:`WebError` naming the path."""
    dest = Path(directory)
    if dest.is_symlink():
        raise WebError("a web folder must be a plain folder, and this is a link", file=str(dest))
    if not dest.exists():
        return
    if not dest.is_dir():
        raise WebError("cannot write the web player here: it is a file, not a folder",
                       file=str(dest))  # fmt: skip
    entries = {e.name for e in dest.iterdir()} - set(_staging(dest))
    if not entries:
        return
    index = dest / "index.html"
    ours = index.is_file() and not index.is_symlink() and MARK in _head(index)
    if not ours:
        raise WebError(
            "the folder is not empty and is not a vtts web folder: give a new or empty folder",
            file=str(dest),
        )
    foreign = _foreign(dest)
    if foreign:
        shown = ", ".join(foreign[:5]) + (" …" if len(foreign) > 5 else "")
        raise WebError(
            f"this vtts web folder also holds files vtts did not write ({shown}); replacing it "
            "would delete them: move them, or give another folder",
            file=str(dest),
        )


def written_files(dest: Path) -> set[str]:
    """What :func:`write_web` wrote into the web folder ``dest`` (POSIX paths): its list
    (:data:`FILES_NAME`), or for a folder written before vtts kept one, the player's files."""
    try:
        with (dest / FILES_NAME).open("rb") as f:
            text = f.read(1 << 20).decode("utf-8", "replace")
    except OSError:
        return set(FOLDER_ENTRIES - {"vendor"}) | {
            p.relative_to(PLAYER_DIR).as_posix()
            for p in (PLAYER_DIR / "vendor").rglob("*")
            if p.is_file()
        }
    return {line for line in text.splitlines() if line} | {FILES_NAME}


def _foreign(dest: Path, most: int = 6) -> list[str]:
    """Up to ``most`` paths in ``dest`` (POSIX, relative) that vtts did not write there: files,
    links or folders that hold none of its files."""
    ours = written_files(dest)
    folders = {str(PurePosixPath(f).parent) for f in ours} - {"."}
    folders |= {str(p) for f in folders for p in PurePosixPath(f).parents} - {"."}
    found: list[str] = []
    staging = set(_staging(dest))
    for top, dirs, files in os.walk(dest):
        rel = PurePosixPath(Path(top).relative_to(dest).as_posix())
        for name in sorted(dirs):
            path = (rel / name).as_posix()
            if rel == PurePosixPath(".") and name in staging:
                dirs.remove(name)
            elif path not in folders or (Path(top) / name).is_symlink():
                found.append(path + "/")
                dirs.remove(name)  # os.walk lists links to folders among the folders
        found += sorted(p for n in files if (p := (rel / n).as_posix()) not in ours)
        if len(found) >= most:
            break
    return found[:most]


def _staging(dest: Path) -> list[str]:
    """The hidden folders of earlier writes into ``dest`` that were killed before cleaning up."""
    with contextlib.suppress(OSError):
        return [
            e.name for e in dest.iterdir()
            if e.name.startswith(STAGING_PREFIX) and e.is_dir() and not e.is_symlink()
        ]  # fmt: skip
    return []


def _head(path: Path) -> str:
    with contextlib.suppress(OSError), path.open("rb") as f:
        return f.read(4096).decode("utf-8", "replace")
    return ""


def write_web(
    directory: str | os.PathLike[str],
    models: list,
    params,
    fps: float,
    *,
    audio: str | os.PathLike[str] | None = None,
    roots=None,
    camera=None,
    size: tuple[int, int] = (352, 288),
    layout: str = "row",
    viewpoint: str | None = None,
    background=None,
    title: str | None = None,
) -> Path:
    """Write the web player of ``models`` animated by ``params`` into the folder ``directory``.

    ``models``, ``params`` (``(T, N_PARAMS)``, or one such array per model), ``fps``, ``roots``,
    ``camera``, ``size``, ``layout`` and ``viewpoint`` are those of
    :func:`vtts.export.gltf.write_gltf`, which writes the ``.glb``; the player looks through its
    ``vtts`` camera, the camera of ``vtts render`` for ``size``. ``audio`` is a sound file (WAV,
    FLAC, …) that starts with the first frame; it is encoded as AAC (``speech.m4a``), and the
    animation follows its clock. ``background`` is the page's color as
    :func:`~vtts.render.color.parse_background` gives it (RGB in 0–1, or ``"transparent"``;
    default: vtts render's). ``title`` is the page's title (default: the models' names). Returns
    the folder's path."""
    from vtts.export.gltf import write_gltf

    dest = Path(directory)
    check_web_folder(dest)
    audio_seconds = _audio_seconds(audio) if audio is not None else 0.0
    n_frames = _frame_count(params)
    if not (np.isfinite(fps) and fps > 0):
        raise WebError(f"the frame rate must be a positive number, got {fps}")
    created = not dest.exists()
    dest.mkdir(parents=True, exist_ok=True)
    for stale in _staging(dest):
        shutil.rmtree(dest / stale, ignore_errors=True)
    tmp = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, suffix=".part", dir=dest))
    try:
        write_gltf(
            tmp / GLB_NAME, models, params, fps,
            roots=roots, camera=camera, size=size, layout=layout, viewpoint=viewpoint,
        )  # fmt: skip
        if audio is not None:
            encode_aac(audio, tmp / AUDIO_NAME)
        for script in ("player.js", "head.js"):
            shutil.copy2(PLAYER_DIR / script, tmp / script)
        shutil.copytree(PLAYER_DIR / "vendor", tmp / "vendor")
        from vtts.export.gltf import unique_names

        # the names the .glb gives its heads' root nodes: a model given twice is cybatt-2 there
        names = unique_names(
            [getattr(m, "name", None) or f"head {i + 1}" for i, m in enumerate(models)]
        )
        config = {
            "glb": GLB_NAME,
            "audio": AUDIO_NAME if audio is not None else None,
            "fps": float(fps),
            "frames": int(n_frames),
            "duration": max(n_frames / fps, audio_seconds),
            "heads": names,
            "size": [int(size[0]), int(size[1])],
        }
        page = Template((PLAYER_DIR / "index.html").read_text(encoding="utf-8")).substitute(
            title=html.escape(title or " and ".join(names) + " — vtts"),
            background=css_color(background),
            config=script_json(config),
        )
        (tmp / "index.html").write_text(page, encoding="utf-8")
        files = sorted(p.relative_to(tmp).as_posix() for p in tmp.rglob("*") if p.is_file())
        (tmp / FILES_NAME).write_text("\n".join([*files, FILES_NAME]) + "\n", encoding="utf-8")
        swap_entries(tmp, dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        if created:
            shutil.rmtree(dest, ignore_errors=True)
        raise
    shutil.rmtree(tmp, ignore_errors=True)
    return dest


def swap_entries(new: Path, dest: Path) -> None:
    """Move the entries of the finished folder ``new`` (inside ``dest``) into ``dest``,
    ``index.html`` last, so a page is never served before what it loads; the entries of the
    previous web folder are moved aside into ``new`` first and put back if a move fails."""
    order = sorted((e.name for e in new.iterdir()), key=lambda n: n == "index.html")
    old = new / ".previous"  # inside new: removed with it
    old.mkdir()
    # what the previous write put at the top (checked to be nothing else), the index first
    previous = sorted(
        {PurePosixPath(f).parts[0] for f in written_files(dest)} & {e.name for e in dest.iterdir()},
        key=lambda n: n != "index.html",
    )
    moved: list[str] = []
    placed: list[str] = []
    try:
        for name in previous:
            os.replace(dest / name, old / name)
            moved.append(name)
        for name in order:
            os.replace(new / name, dest / name)
            placed.append(name)
    except BaseException:
        for name in placed:
            with contextlib.suppress(OSError):
                os.replace(dest / name, new / name)
        for name in moved:
            with contextlib.suppress(OSError):
                os.replace(old / name, dest / name)
        raise


def script_json(value) -> str:
    """``value`` as JSON to put inside a ``<script>`` element: ``<``, ``>`` and ``&`` written as
    ``\\u003c`` … so that no text in it (a model named ``</script>`` or ``<!--<script>``, which
    puts the HTML parser in a state where ``</script>`` no longer ends the element) is read as
    markup; JSON reads the escapes back as the same characters."""
    text = json.dumps(value, ensure_ascii=True)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _frame_count(params) -> int:
    """Frames in ``params``: a ``(T, N_PARAMS)`` array, or a list of them (one per model)."""
    if isinstance(params, np.ndarray) and params.ndim == 2:
        return int(params.shape[0])
    return max((len(p) for p in params), default=0)


def css_color(background) -> str:
    """A background as the page's CSS: None → vtts render's, ``"transparent"``, or an RGB
    triple in 0–1 → ``#rrggbb``."""
    if background is None:
        return DEFAULT_BACKGROUND
    if isinstance(background, str):
        if background == "transparent":
            return "transparent"
        raise WebError(f"a page background is an RGB color or 'transparent', got {background!r}")
    rgb = np.clip(np.asarray(background, dtype=np.float64).reshape(-1)[:3], 0.0, 1.0)
    if rgb.shape != (3,) or not np.isfinite(rgb).all():
        raise WebError(f"a page background is an RGB color in 0–1, got {background!r}")
    return "#" + "".join(f"{round(float(c) * 255):02x}" for c in rgb)


def _audio_seconds(audio: str | os.PathLike[str]) -> float:
    """The duration of a sound file soundfile reads; :class:`WebError` when it cannot."""
    import soundfile

    path = Path(audio)
    if not path.is_file():
        raise WebError("no such audio file", file=str(path))
    try:
        info = soundfile.info(str(path))
    except (soundfile.SoundFileError, RuntimeError, OSError) as e:
        raise WebError(f"cannot read the audio: {e}", file=str(path)) from None
    return float(info.frames) / float(info.samplerate) if info.samplerate else 0.0


def encode_aac(audio: str | os.PathLike[str], out: str | os.PathLike[str]) -> Path:
    """Encode a sound file as AAC in an ``.m4a`` (MP4) with the ffmpeg of ``imageio-ffmpeg``.

    The file carries an edit list that trims the encoder's priming samples, which browsers honour
    (Chromium decodes a click at 1.000 s of the WAV at 1.000 s of the ``.m4a``), so the audio's
    clock is the WAV's. ``+faststart`` puts the index first: playback starts before the whole
    file has arrived."""
    from vtts.media import ffmpeg_exe

    out = Path(out)
    result = subprocess.run(
        [
            ffmpeg_exe(),
            "-nostdin",
            "-v",
            "error",
            "-y",
            "-i",
            str(audio),
            "-vn",
            "-c:a",
            "aac",
            "-b:a",
            "96k",
            "-movflags",
            "+faststart",
            str(out),
        ],  # fmt: skip
        capture_output=True,
        text=True,
    )
    if result.returncode != 0:
        tail = "\n".join(result.stderr.strip().splitlines()[-6:])
        raise WebError(f"ffmpeg could not encode the audio as AAC: {tail}", file=str(audio))
    return out
