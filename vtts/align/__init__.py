"""Forced alignment of a transcript to recorded speech (``vtts say --audio VOICE.wav``).

:func:`align` gives espeak-ng's phones, words and bookmarks of the transcript in the recording's
clock; :mod:`vtts.align.score` measures an alignment against another engine's own timings.
"""

from vtts.align.aligner import AlignedWord, Alignment, align

__all__ = ["AlignedWord", "Alignment", "align"]
