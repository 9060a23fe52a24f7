"""Checks on values users pass in: each bad value gets one clear ValueError that names it and
says what it accepts, raised before anything is built or reaches MuJoCo."""

from __future__ import annotations

import math
import numbers
from typing import Iterable, Sequence


def check_choice(kind: str, value, choices: Sequence[str], *, also: str | None = None):
    """`value` if it is one of `choices`, else "unknown KIND VALUE; valid KINDs: ..."
    (`also` names a further valid value that is not a string, e.g. "None")."""
    if isinstance(value, str) and value in choices:
        return value
    valid = ", ".join(([also] if also else []) + list(choices))
    raise ValueError(f"unknown {kind} {value!r}; valid {kind}s: {valid}")


def check_names(kind: str, names: Iterable[str], valid: Iterable[str]) -> None:
    """Raises "unknown KIND(s) 'a', 'b'; valid KINDs: ..." for names not in `valid`."""
    valid = sorted(valid)
    unknown = sorted(set(names) - set(valid))
    if unknown:
        raise ValueError(f"unknown {kind}(s) {', '.join(map(repr, unknown))}; "
                         f"valid {kind}s: {', '.join(valid)}")


def check_bool(name: str, value) -> bool:
    """`value` if it is a bool (not a string such as "no", nor a number)."""
    if isinstance(value, bool):
        return value
    raise ValueError(f"{name} must be True or False, got {value!r}")


def check_number(name: str, value, *, minimum: float | None = None,
                 maximum: float | None = None, above: float | None = None,
                 integer: bool = False) -> float | int:
    """`value` as a float (an int if `integer`) if it is a finite real number (not a bool or
    a string) within the bounds: `minimum` <= value <= `maximum`, `above` < value."""
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if integer:
        real = real and isinstance(value, numbers.Integral)
    if not real or not math.isfinite(value):
        kind = "a whole number" if integer else "a finite number"
        raise ValueError(f"{name} must be {kind}{_bounds(minimum, maximum, above)}, "
                         f"got {value!r}")
    if ((minimum is not None and value < minimum) or (maximum is not None and value > maximum)
            or (above is not None and value <= above)):
        raise ValueError(f"{name} must be{_bounds(minimum, maximum, above)}, got {value!r}")
    return int(value) if integer else float(value)


def check_vector(name: str, value, size: int, **bounds) -> tuple[float, ...]:
    """`value` as a tuple of `size` floats, each checked like `check_number(**bounds)`."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Iterable):
        raise ValueError(f"{name} must be a sequence of {size} numbers, got {value!r}")
    items = tuple(value)
    if len(items) != size:
        raise ValueError(f"{name} must have {size} number(s), got {len(items)}: {value!r}")
    return tuple(check_number(f"{name}[{i}]", item, **bounds) for i, item in enumerate(items))


def _bounds(minimum, maximum, above) -> str:
    parts = []
    if above is not None:
        parts.append(f"> {above:g}")
    if minimum is not None:
        parts.append(f">= {minimum:g}")
    if maximum is not None:
        parts.append(f"<= {maximum:g}")
    return (" " + " and ".join(parts)) if parts else ""
