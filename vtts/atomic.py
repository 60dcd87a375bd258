"""Writing outputs so that nothing is ever half-written.

Every file vtts produces goes through :func:`atomic_path`: the data is written to a temporary name
in the destination folder and renamed over the destination only when writing completed. An
exception or Ctrl-C leaves the destination untouched and removes the temporary file.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it to ``path`` on success.

    Use it for tools that write a file themselves (ffmpeg, soundfile)::

        with atomic_path("out.mp4") as tmp:
            run_encoder(output=tmp)
    """
    dest = Path(path)
    dest.parent.mkdir(parents=True, exist_ok=True)
    # a short temporary name: a 250-character output name must not fail on its temporary's
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{dest.name[:40]}.", suffix=".part" + dest.suffix[:16], dir=dest.parent
    )
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        # mkstemp makes the file private (0600); a finished output gets the usual permissions
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, dest)
    except BaseException as e:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        if isinstance(e, OSError) and e.filename in (str(tmp), tmp) and e.errno is not None:
            # name the output the user gave, not its hidden temporary
            raise OSError(e.errno, e.strerror, str(dest)) from None
        raise


def current_umask() -> int:
    """The process's umask (read by setting and restoring it)."""
    mask = os.umask(0o22)
    os.umask(mask)
    return mask


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def check_outputs(
    outputs: list[str | os.PathLike[str]], inputs: list[str | os.PathLike[str]]
) -> None:
    """Refuse, before anything is written, outputs that would destroy something: an output that
    is one of the ``inputs`` (the same file by any name), two outputs that are the same file,
    and an output that exists but is not a plain file (a link, a device, a FIFO, a folder: the
    rename would replace it, and as root ``-o /dev/null`` would replace the system's). Raises
    :class:`~vtts.errors.VttsError` naming the path."""
    from vtts.errors import VttsError

    def same(a: Path, b: Path) -> bool:
        try:
            return a.exists() and b.exists() and os.path.samefile(a, b)
        except OSError:
            return False

    seen: list[Path] = []
    for out in map(Path, outputs):
        if out.is_symlink():
            raise VttsError("an output must be a plain file, and this is a link", file=str(out))
        if out.is_dir():
            raise VttsError("cannot write here: it is a folder", file=str(out))
        if out.exists() and not out.is_file():
            raise VttsError(
                "an output must be a plain file, and this is not a regular file (a device, a "
                "pipe …)",
                file=str(out),
            )
        for inp in map(Path, inputs):
            if same(out, inp) or out.resolve() == inp.resolve():
                raise VttsError(
                    f"this output is also an input ({inp}): writing it would destroy it",
                    file=str(out),
                )
        for other in seen:
            if out.resolve() == other.resolve() or same(out, other):
                raise VttsError(f"two outputs name the same file ({other})", file=str(out))
        seen.append(out)


def replace_folder(new: str | os.PathLike[str], dest: str | os.PathLike[str]) -> None:
    """Rename the finished folder ``new`` to ``dest`` (same filesystem). A previous ``dest`` is
    moved aside first and removed after, or put back when the rename fails, so that ``dest`` is
    at every moment either the old folder or the new one, whole."""
    new, dest = Path(new), Path(dest)
    if not dest.exists():
        os.replace(new, dest)
        return
    if dest.is_dir() and not any(dest.iterdir()):
        os.replace(new, dest)  # rename(2) replaces an empty folder
        return
    old = Path(tempfile.mkdtemp(prefix=f".{dest.name[:40]}.", suffix=".old", dir=dest.parent))
    os.replace(dest, old)  # replaces the empty placeholder folder
    try:
        os.replace(new, dest)
    except BaseException:
        os.replace(old, dest)
        raise
    shutil.rmtree(old, ignore_errors=True)
