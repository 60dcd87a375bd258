"""The error hierarchy of vtts: one root, specific subclasses.

Every error a user can cause with bad input is a :class:`VttsError`; the CLI prints it as
``FILE:LINE:COL: error: MESSAGE`` and exits non-zero, never with a traceback.
"""

from __future__ import annotations


class VttsError(Exception):
    """Root of every error vtts raises for bad input or a missing resource.

    ``file``, ``line`` and ``column`` (1-based) locate the problem when it has a place in a file;
    ``context`` is an optional excerpt of the offending line with a caret under the column.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | None = None,
        context: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.column = column
        self.context = context

    def location(self) -> str:
        """``FILE:LINE:COL`` as far as it is known (empty string when nothing is)."""
        parts = [self.file or "<input>"] if (self.file or self.line) else []
        if self.line is not None:
            parts.append(str(self.line))
            if self.column is not None:
                parts.append(str(self.column))
        return ":".join(parts)

    def __str__(self) -> str:
        loc = self.location()
        text = f"{loc}: {self.message}" if loc else self.message
        if self.context:
            text += "\n" + self.context
        return text


class VrmlError(VttsError):
    """A VRML97 file breaks the standard."""


class VrmlSyntaxError(VrmlError):
    """The text is not VRML97 syntax (unexpected character or token)."""


class VrmlSemanticError(VrmlError):
    """The syntax is fine but a rule of the standard is broken (unknown node or field, wrong value
    type, USE of an undefined name, IS outside a PROTO, incompatible ROUTE, ...)."""


class VrmlLimitError(VrmlError):
    """The file exceeds a safety limit (size, nesting depth)."""


class VrmlUrlError(VrmlError):
    """A url field points outside the file's folder or at the network."""


class FapError(VttsError):
    """A FAP file, FAP value or FAP name is invalid."""


class ModelError(VttsError):
    """A personalized model (scene plus tables) is inconsistent or cannot be found."""


class AdtError(ModelError):
    """An Animation Definition Table is invalid."""


class AvatarError(VttsError):
    """An avatar (ARKit blendshapes, Oculus visemes) or its curves cannot be read or written: a
    bad recipe table, an unknown curves format, a blendshape name that is not ARKit's."""


class VttsWarning(UserWarning):
    """A problem vtts works around (lenient parsing, FAPs a model cannot show); carries the same
    location attributes as :class:`VttsError`."""

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.column = column

    def __str__(self) -> str:
        parts = [p for p in (self.file, self.line, self.column) if p is not None]
        loc = ":".join(str(p) for p in parts)
        return f"{loc}: {self.message}" if loc else self.message


class RenderError(VttsError):
    """Rendering or writing an output (image, video, audio) failed."""


class ExportError(RenderError):
    """Exporting an animation (glTF) failed, or what it was given is invalid."""


class AnalysisError(VttsError):
    """Estimating FAPs from video failed, or its input (video, PNG folder, FAP list) is invalid."""


class BookmarkError(VttsError):
    """Text with bookmarks is malformed or names something unknown (``column`` is 1-based)."""


class SpeechError(VttsError):
    """Speech synthesis failed or its input (voice, phoneme file, audio) is invalid."""


class CodingError(FapError):
    """A FAP bitstream (``.fbs``) is corrupt, truncated or inconsistent, or a stream cannot be
    coded.

    ``offset`` is the 0-based byte offset in the bitstream where the problem was found, and the
    message starts with ``byte N:``; it is ``None`` (and the message has no prefix) for problems
    that have no place in a bitstream, such as a value too large for the encoder. ``reason`` is the
    message without the prefix.
    """

    def __init__(self, message: str, *, offset: int | None = None, file: str | None = None) -> None:
        super().__init__(f"byte {offset}: {message}" if offset is not None else message, file=file)
        self.reason = message
        self.offset = offset


class FitError(VttsError):
    """Fitting a head to a photograph failed, or its input (image, landmarks) is invalid, such as
    an image that is not an ``(H, W, 3) uint8`` RGB array."""


class ServeError(VttsError):
    """``vtts serve`` cannot start (a port in use, a model it cannot load), or a client's message
    is not one the protocol allows (the error message on its socket says which)."""
