"""How the commands write counts: "1 episode", "20 episodes", "500,000 steps", never
"1 episodes"."""

from __future__ import annotations


def counted(count: int, noun: str) -> str:
    """`count` (with thousands separators, as the commands write steps) and `noun`, plural
    unless the count is one."""
    return f"{count:,} {noun if count == 1 else noun + 's'}"
