"""MPEG-4 Facial Animation Parameters: the FAP tables, FAPUs and FAP streams (``.fap`` files).

- :mod:`vtts.fap.table`: the 68 FAPs (:data:`FAPS`, :func:`fap`), visemes and expressions;
- :mod:`vtts.fap.fapu`: :class:`Fapu`, what one FAP unit means on a given face;
- :mod:`vtts.fap.stream`: :class:`FapStream` and reading/writing ``.fap`` files.
"""

from __future__ import annotations

from vtts.fap.fapu import AU, FAPU_DIVISOR, Fapu
from vtts.fap.stream import (
    EXPRESSION_FIELDS,
    TRANSLATION_AXES,
    VERSIONS,
    VISEME_FIELDS,
    FapStream,
    FapWarning,
    format_fap,
    parse_fap,
    read_fap,
    write_fap,
)
from vtts.fap.table import (
    EXPRESSIONS,
    FAPS,
    N_FAPS,
    VISEMES,
    Expression,
    FapDef,
    Viseme,
    expression,
    fap,
    viseme,
)

__all__ = [
    "AU",
    "EXPRESSIONS",
    "EXPRESSION_FIELDS",
    "FAPS",
    "FAPU_DIVISOR",
    "N_FAPS",
    "TRANSLATION_AXES",
    "VERSIONS",
    "VISEMES",
    "VISEME_FIELDS",
    "Expression",
    "FapDef",
    "FapStream",
    "FapWarning",
    "Fapu",
    "Viseme",
    "expression",
    "fap",
    "format_fap",
    "parse_fap",
    "read_fap",
    "viseme",
    "write_fap",
]
