"""Reading a number a page writes and comparing it with the run's: the page is under test, the run
is the truth. A number is compared at the precision the page writes it (its decimals), so a page
that rounds differently from the run, or a run that moved, fails."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NUM = r"([−-]?\d+(?:\.\d+)?)"


def page(name: str) -> str:
    """The text of docs/NAME (or of a path relative to the repository)."""
    path = ROOT / "docs" / name if "/" not in name else ROOT / name
    return path.read_text()


def section(text: str, start: str, end: str | None = None) -> str:
    """The text from the line holding ``start`` up to (not including) ``end`` (or the next heading)."""
    i = text.index(start)
    if end is None:
        m = re.compile(r"^#", re.M).search(text, text.index("\n", i) + 1)
        return text[i:m.start() if m else len(text)]
    return text[i:text.index(end, i)]


def table_rows(text: str, after: str) -> dict:
    """{first cell: [cells]} of the first Markdown table after the line containing ``after``."""
    start = text.index(after)
    rows = {}
    for line in text[start:].splitlines()[1:]:
        if not line.startswith("|"):
            if rows:
                break
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if set(cells[0]) <= set("-: "):
            continue
        rows[cells[0]] = cells
    return rows


def as_float(text: str) -> float:
    return float(text.replace("−", "-").replace(",", ""))


def same_as_written(text: str, value: float) -> bool:
    """value rounded to the decimals of text equals text (a minus sign either way; a written plus
    sign asks for a positive value)."""
    text = text.replace("−", "-")
    if text.startswith("+"):
        return value > 0 and same_as_written(text[1:], value)
    decimals = len(text.split(".")[1]) if "." in text else 0
    got = f"{value:.{decimals}f}"
    return got == text or (got == "-" + text.lstrip("-") and float(text) == 0.0)


def same_to_figures(text: str, value: float) -> bool:
    """value rounded to the significant figures of text equals text; an integer's trailing zeros
    are not significant ("13100" is 131 hundreds)."""
    text = text.replace("−", "-")
    digits = text.lstrip("-").replace(".", "").lstrip("0")
    figures = len(digits if "." in text else digits.rstrip("0")) or 1
    return float(f"{value:.{figures}g}") == float(text)


def check(text: str, patterns: list) -> None:
    """Each (regex with one number group, value) must match ``text`` once and read ``value`` at its
    written precision."""
    for pattern, value in patterns:
        found = re.findall(pattern, text)
        assert len(found) == 1, f"{pattern!r} matches {len(found)} times in {text[:300]!r}"
        assert same_as_written(found[0], value), f"the page writes {found[0]} for {pattern!r}, the run gives {value!r}"
