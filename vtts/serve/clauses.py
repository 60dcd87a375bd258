"""Text that arrives in pieces cut into clauses, the units ``vtts serve`` speaks one at a time.

A clause ends after ``.``, ``!``, ``?``, ``;``, ``:`` or ``,`` followed by white space, outside
a bookmark (``<smile 2s>``) and not escaped (``\\,``); a clause with no such mark ends at the
white space after :data:`MAX_CLAUSE_WORDS` words. A full stop inside a number (``3.5``) or a
mark at the very end of the text so far waits for what comes next. A clause with nothing to say
(only bookmarks and spaces) is joined to the next one.
"""

from __future__ import annotations

#: The marks after which a clause ends.
CLAUSE_MARKS = frozenset(".!?;:,")
#: The most words of a clause without a mark: a text without punctuation (a language model that
#: writes none) still starts speaking.
MAX_CLAUSE_WORDS = 20


def has_words(text: str) -> bool:
    """Whether ``text`` has something to say outside its bookmarks."""
    depth = False
    for ch in text:
        if ch == "<":
            depth = True
        elif ch == ">":
            depth = False
        elif not depth and ch.isalnum():
            return True
    return False


class ClauseCutter:
    """Cuts appended text into clauses: :meth:`feed` returns the clauses completed so far,
    :meth:`flush` the rest."""

    def __init__(self, max_words: int = MAX_CLAUSE_WORDS) -> None:
        self.max_words = max_words
        self.pending = ""
        self._scanned = 0  # characters of pending already looked at
        self._in_bookmark = False
        self._escaped = False
        self._words = 0  # words of the clause so far
        self._in_word = False

    def __len__(self) -> int:
        """Characters waiting to be cut."""
        return len(self.pending)

    def feed(self, text: str) -> list[str]:
        """Add ``text``; the clauses it completes, in order."""
        self.pending += text
        out: list[str] = []
        start = 0
        i = self._scanned
        p = self.pending
        while i < len(p):
            ch = p[i]
            if self._escaped:
                self._escaped = False
            elif ch == "\\":
                self._escaped = True
            elif self._in_bookmark:
                self._in_bookmark = ch != ">"
            elif ch == "<":
                self._in_bookmark = True
            elif ch.isspace():
                if self._in_word:
                    self._words += 1
                    self._in_word = False
                before = p[i - 1] if i > start else ""
                ends = before in CLAUSE_MARKS and (i < 2 or p[i - 2] != "\\")
                if (ends or self._words >= self.max_words) and has_words(p[start:i]):
                    out.append(p[start:i].strip())
                    start = i + 1
                    self._words = 0
            else:
                self._in_word = True
            i += 1
        self.pending = p[start:]
        self._scanned = len(self.pending)
        return out

    def flush(self) -> list[str]:
        """The text not yet cut, as the last clause (none when it has nothing to say)."""
        rest = self.pending.strip()
        self.clear()
        return [rest] if has_words(rest) else []

    def clear(self) -> None:
        """Forget the text not yet cut (after ``stop``)."""
        self.pending = ""
        self._scanned = 0
        self._in_bookmark = self._escaped = self._in_word = False
        self._words = 0
