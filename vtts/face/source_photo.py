"""The photo a head was fitted to, recorded beside it: what ``--background photo`` draws the
head into (:mod:`vtts.render.talking_photo`).

``adi fit`` writes the photo (as fitted: a photo larger than
:data:`~vtts.fit.photo.WORK_SIZE` scaled down) as ``OUT-photo.png`` beside ``OUT.wrl``; a head
made for a video (``vtts analyze --model auto``) already holds its first frame as the top-left
corner of ``OUT-frame.png``. Either way the scene names the file and the photo's size in a
WorldInfo, as the temporal tables are kept (:data:`TITLE`)::

    DEF SOURCE_PHOTO WorldInfo {
      title "vtts:SourcePhoto"
      info [ "me-photo.png" "512 512" ]
    }

The photo is the top-left ``W × H`` pixels of that image, which lies in the model's folder (the
url resolves as the model's textures do: inside that folder or the allowed url roots).
"""

from __future__ import annotations

import numpy as np

from vtts.errors import RenderError
from vtts.vrml import Scene, parse

#: The WorldInfo title that marks the record of the source photo.
TITLE = "vtts:SourcePhoto"
#: Its DEF name.
DEF_NAME = "SOURCE_PHOTO"


def record_photo(scene: Scene, url: str, width: int, height: int) -> None:
    """Name the source photo in ``scene`` (changed in place): the image file ``url`` (relative
    to the model's folder) whose top-left ``width`` × ``height`` pixels are the photo. A record
    already there is replaced."""
    if '"' in url or "\\" in url or "\n" in url:
        raise RenderError(f"the photo's file name cannot be written in VRML: {url!r}")
    text = (
        f'#VRML V2.0 utf8\nDEF {DEF_NAME} WorldInfo {{\n  title "{TITLE}"\n'
        f'  info [ "{url}" "{int(width)} {int(height)}" ]\n}}\n'
    )
    node = parse(text).roots[0]
    for i, statement in enumerate(scene.statements):
        if _is_record(statement):
            scene.statements[i] = node
            break
    else:
        at = 0
        while at < len(scene.statements) and _type(scene.statements[at]) == "WorldInfo":
            at += 1
        scene.statements.insert(at, node)
    scene.defs[DEF_NAME] = node


def photo_record(scene: Scene) -> tuple[str, tuple[int, int]] | None:
    """``(url, (W, H))`` of the source photo ``scene`` names, or None when it names none."""
    for node in scene.find("WorldInfo"):
        if _is_record(node):
            info = [str(v) for v in node.expand()["info"]]
            try:
                w, h = (int(v) for v in info[1].split())
            except (IndexError, ValueError):
                raise RenderError(
                    f"the scene's {TITLE} WorldInfo must hold a file name and 'WIDTH HEIGHT', "
                    f"got {info}"
                ) from None
            if not (0 < w <= 1 << 16 and 0 < h <= 1 << 16):
                raise RenderError(f"the source photo's size {w}x{h} is not a photo's")
            return info[0], (w, h)
    return None


def source_photo(model) -> np.ndarray:
    """The photo ``model`` (a :class:`~vtts.face.FaceModel`) was fitted to, ``(H, W, 3)
    uint8`` RGB; raises :class:`~vtts.errors.RenderError` when the model records none or its
    file is missing or not that photo."""
    from PIL import Image

    from vtts.limits import MAX_PHOTO_PIXELS
    from vtts.vrml import resolve_url

    where = str(model.path) if model.path is not None else model.name
    record = photo_record(model.scene)
    if record is None:
        raise RenderError(
            f"{where}: --background photo draws the head into the photo it was fitted to, and "
            "this model records none (a head made by adi fit or vtts analyze --model auto does)"
        )
    url, (w, h) = record
    base = model.path.parent if model.path is not None else None
    path = resolve_url([url], base, getattr(model.scene, "url_roots", ()))
    if path is None:
        raise RenderError(
            f"{where}: its source photo {url!r} is not found beside it (or lies outside the "
            "allowed folders)"
        )
    try:
        with Image.open(path) as im:
            if im.size[0] * im.size[1] > MAX_PHOTO_PIXELS:
                raise RenderError(f"{path}: the source photo is larger than the limit")
            if im.size[0] < w or im.size[1] < h:
                raise RenderError(
                    f"{path}: the source photo is {im.size[0]}x{im.size[1]} pixels, smaller than "
                    f"the {w}x{h} the model records"
                )
            rgb = np.asarray(im.convert("RGB"))
    except (OSError, SyntaxError, ValueError) as e:
        raise RenderError(f"{path}: the source photo is not a readable image ({e})") from None
    return np.ascontiguousarray(rgb[:h, :w])


def _type(statement) -> str:
    return getattr(statement, "type_name", "")


def _is_record(node) -> bool:
    node = node.expand() if hasattr(node, "expand") else node
    if getattr(getattr(node, "type", None), "name", None) != "WorldInfo":
        return False
    return str(node["title"]) == TITLE
