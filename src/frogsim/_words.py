"""Words for messages: a count with its noun in the right number ("1 muscle", "12 muscles")."""
from __future__ import annotations


def count(n, noun: str, plural: str | None = None) -> str:
    """"1 point", "2 points", "0 points"; ``plural`` for a noun not made plural by an s
    ("1 trace(s)" is never written)."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"
