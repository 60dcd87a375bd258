"""docs/avatars.md shows the recipe table as it is: every row of vtts/data/arkit_recipes.tsv.

After changing the table, ``python tests/avatar/test_docs_tables.py`` prints the three Markdown
tables to paste into docs/avatars.md.
"""

from __future__ import annotations

from pathlib import Path

from vtts.avatar.arkit import OCULUS_VISEMES, Recipe, recipes
from vtts.avatar.sapi import ALLOWED, FROM_MPEG4
from vtts.fap import EXPRESSIONS, VISEMES, fap

DOC = Path(__file__).resolve().parents[2] / "docs" / "avatars.md"


def _shapes(r: Recipe) -> str:
    return ", ".join(f"`{n}` {w:g}" for n, w in r.shapes.items()) or "—"


def tables() -> list[list[str]]:
    """The FAP, viseme and expression tables as Markdown lines."""
    t = recipes()
    faps = [
        "| FAP | name | direction | amplitude (weight 1 ≙) | ARKit shapes |",
        "|---|---|---|---|---|",
    ]
    for r in t.fap_rows():
        d = fap(r.number)
        sign = "+" if r.sign > 0 else "−"
        faps.append(f"| {r.number} | {d.name} | {sign} | {r.amplitude:g} {d.fapu} | {_shapes(r)} |")
    visemes = [
        "| viseme | phonemes | Oculus | SAPI (Azure) | ARKit shapes at weight 1 |",
        "|---|---|---|---|---|",
    ]
    for v in range(15):
        others = sorted(ALLOWED[v] - {FROM_MPEG4[v]})
        sapi = str(FROM_MPEG4[v]) + (f" ({', '.join(map(str, others))} by phone)" if others else "")
        shapes = _shapes(t.viseme(v))
        visemes.append(f"| {v} | {VISEMES[v].label} | `{OCULUS_VISEMES[v]}` | {sapi} | {shapes} |")
    expressions = ["| expression | ARKit shapes at weight 1 |", "|---|---|"]
    for e in range(1, 7):
        expressions.append(f"| {e} {EXPRESSIONS[e].name} | {_shapes(t.expression(e))} |")
    return [faps, visemes, expressions]


def test_docs_show_every_row_of_the_table():
    doc = DOC.read_text(encoding="utf-8").splitlines()
    for table in tables():
        missing = [line for line in table if line not in doc]
        assert not missing, f"docs/avatars.md lacks {missing[:3]}: run {__file__}"


if __name__ == "__main__":
    print("\n\n".join("\n".join(t) for t in tables()))
