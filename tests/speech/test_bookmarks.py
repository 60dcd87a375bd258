"""Bookmarked text: the grammar, every kind of bookmark, SSML marks, escapes and errors."""

from __future__ import annotations

import pytest

from vtts.errors import BookmarkError
from vtts.speech.bookmarks import Bookmark, parse_bookmarks


def test_the_issue_example():
    t = parse_bookmarks(
        "Hello <smile 5s> nice to <surprise 1.5s 0.7> meet you <blink> \\<not a bookmark>"
    )
    b = t.bookmarks
    assert [(x.kind, x.name, x.duration, x.amplitude) for x in b] == [
        ("expression", "joy", 5.0, None),
        ("expression", "surprise", 1.5, 0.7),
        ("action", "blink", None, None),
    ]
    assert t.text == "Hello  nice to  meet you  <not a bookmark>"
    assert [x.column for x in b] == [7, 26, 55]
    assert t.ssml() == (
        '<speak>Hello <mark name="b0"/> nice to <mark name="b1"/> meet you <mark name="b2"/> '
        "&lt;not a bookmark&gt;</speak>"
    )


@pytest.mark.parametrize(
    "text, expected",
    [
        ("<fap 3=400 19=1024 1s>", Bookmark("fap", "fap", 1.0, None, {3: 400, 19: 1024})),
        ("<fap open_jaw=-20 300ms>", Bookmark("fap", "fap", 0.3, None, {3: -20})),
        ('<mark name="nod 300ms 0.5"/>', Bookmark("action", "nod", 0.3, 0.5)),
        ('<mark name="happy" />', Bookmark("expression", "joy")),
        ("< look_left 2s >", Bookmark("action", "look_left", 2.0)),
        ("<Surprise>", Bookmark("expression", "surprise")),
    ],
)
def test_bookmark_kinds(text, expected):
    (b,) = parse_bookmarks("Hi " + text + " there").bookmarks
    assert (b.kind, b.name, b.duration, b.amplitude, b.faps) == (
        expected.kind,
        expected.name,
        expected.duration,
        expected.amplitude,
        expected.faps,
    )


@pytest.mark.parametrize(
    "text, column, fragment",
    [
        ("Hi <grin> there", 4, "unknown bookmark <grin>; known names: joy"),
        ("Hi <smile 2>", 4, "amplitude 2 of <smile> must be within 0–1"),
        ("Hi <smile 1s 2s>", 4, "two durations"),
        ("Hi <smile 3=4>", 4, "belongs in a <fap ...> bookmark"),
        ("Hi <fap>", 4, "<fap> needs values"),
        ("Hi <fap 1=3>", 4, "not a MIAP"),
        ("Hi <fap nope=3>", 4, "unknown FAP 'nope'"),
        ("Hi <smile", 5, "cannot read a bookmark here"),
        ("Hi <smile 5x>", 11, "'5x' in <smile> is neither a duration (1.5s, 300ms) nor an"),
        ("Hi <fap 3=1 x>", 13, "nor a FAP value"),
        ('Hi <mark name="x y z"/>', 15, "is not a bookmark"),
    ],
)
def test_errors_have_the_column_and_the_names(text, column, fragment):
    with pytest.raises(BookmarkError) as info:
        parse_bookmarks(text)
    assert info.value.column == column, str(info.value)
    assert fragment in info.value.message


@pytest.mark.parametrize(
    "text, line, column",
    [
        ("Hello \x01 world", None, 7),
        ("Hello\nthere \x0c now", 2, 7),
        ("Hello \ufffe", None, 7),
    ],
)
def test_control_characters_are_refused_at_their_place_in_the_users_text(text, line, column):
    """Not a column of the SSML document that the text becomes (it used to say column 14)."""
    with pytest.raises(BookmarkError, match="cannot be spoken") as info:
        parse_bookmarks(text)
    assert (info.value.line, info.value.column) == (line, column)
    assert "\\x" in info.value.message or "\\u" in info.value.message


@pytest.mark.parametrize(
    "text, line, column, fragment",
    [
        ("Hello\nthere <frown>", 2, 7, "unknown bookmark <frown>"),
        ("a\nb\n <smile 2s 3s>", 3, 2, "<smile> has two durations"),
        ("a\nb <smile", 2, 4, "cannot read a bookmark here"),
    ],
)
def test_errors_in_a_text_of_several_lines_give_the_line(text, line, column, fragment):
    with pytest.raises(BookmarkError) as info:
        parse_bookmarks(text)
    assert (info.value.line, info.value.column) == (line, column)
    assert str(info.value).startswith(f"<input>:{line}:{column}: {fragment}")


def test_escapes_and_plain_text_survive():
    t = parse_bookmarks("a \\< b \\\\ c \\d e")
    assert t.text == "a < b \\ c \\d e" and not t.bookmarks
    with pytest.raises(BookmarkError, match="unknown bookmark <marker>"):
        parse_bookmarks("a <marker> b")  # 'mark' starts an SSML mark only as <mark name=…>


def test_unknown_names_list_what_the_model_knows():
    with pytest.raises(BookmarkError) as info:
        parse_bookmarks("Hi <grin>", known={"joy", "surprise"})
    msg = info.value.message
    assert "known names: joy (happiness, happy, smile), surprise (surprised), blink" in msg
    assert "sadness" not in msg


@pytest.mark.parametrize(
    "text, spoken, moved",
    [
        ("people <sad>.", "people.", [0]),
        ("people <sad> .", "people.", [0]),
        ("Hello <smile>, nice <blink>!", "Hello, nice!", [0, 1]),
        ("Why <surprise>? Oh <fear>; so <joy>: yes", "Why? Oh; so: yes", [0, 1, 2]),
        ("people <sad> <blink>. Bye", "people. Bye", [0, 1]),
        ("well <sad>?!\n", "well?!\n", [0]),
        ('"people <sad>." he said', '"people." he said', [0]),
        ("a <sad>.<joy> b", "a. b", [0]),
        # nothing to attach to, or not punctuation standing alone: as written
        ("<sad>. Hello", ". Hello", []),
        ("Hello. <sad>. Bye", "Hello. . Bye", []),
        ("a <sad>.5 b", "a .5 b", []),
        ("Hello <smile> nice", "Hello  nice", []),
    ],
)
def test_punctuation_after_bookmarks_stays_on_its_word(text, spoken, moved):
    t = parse_bookmarks(text)
    assert t.text == spoken
    assert sorted(t.before_punctuation) == moved
    # the bookmarks keep their order and their columns in the text as written
    assert [b.column for b in t.bookmarks] == [i + 1 for i, c in enumerate(text) if c == "<"]
    assert all(f'<mark name="b{k}"/>' in t.ssml() for k in range(len(t.bookmarks)))


def test_punctuation_is_spoken_before_the_mark():
    assert parse_bookmarks("people <sad> <blink>. Bye").ssml() == (
        '<speak>people.<mark name="b0"/><mark name="b1"/> Bye</speak>'
    )
