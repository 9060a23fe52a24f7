"""How the commands write counts: "1 episode", "20 episodes", never "1 episodes"."""

from __future__ import annotations


def counted(count: int, noun: str, plural: str | None = None, *, grouped: bool = False) -> str:
    """`count` and `noun`, the noun plural unless the count is one (`plural`, or `noun` +
    "s"); `grouped` writes the count with thousands separators (500,000)."""
    number = f"{count:,}" if grouped else str(count)
    return f"{number} {noun if count == 1 else plural or noun + 's'}"
