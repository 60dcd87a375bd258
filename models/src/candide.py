"""Candide-3 for the bundled heads: the reader and the subdivision live in :mod:`vtts.fit.candide`
(``adi fit`` refines the same face with the same matrix); this name keeps the model scripts'
imports short."""

from vtts.fit.candide import (  # noqa: F401
    LEVELS,
    SUBDIVISION_CORNERS,
    Candide,
    boundary_loops,
    compact,
    face_triangles,
    read_wfm,
    subdivision_matrix,
)
