"""Checks on values users pass in: each bad value gets one clear ValueError that names it and
says what it accepts, raised before anything is built or reaches MuJoCo."""

from __future__ import annotations

import contextlib
import contextvars
import inspect
import math
import numbers
import os
import pathlib
import tempfile
from collections.abc import Set as AbstractSet
from typing import Iterable, Mapping, Sequence

import numpy as np


_SPELLINGS: contextvars.ContextVar[Mapping[str, str]] = contextvars.ContextVar(
    "spellings", default={})


@contextlib.contextmanager
def spelled(spellings: Mapping[str, str]):
    """Within it, a refusal names a setting as `spellings` give it (a field's name by its
    command-line flag: "--train-every", not "train_every", for the user of a command), else
    by its own name (`spelling`)."""
    token = _SPELLINGS.set(spellings)
    try:
        yield
    finally:
        _SPELLINGS.reset(token)


def spelling(name: str) -> str:
    """How a refusal names the setting `name` where it is made (`spelled`)."""
    return _SPELLINGS.get().get(name, name)


def check_choice(kind: str, value, choices: Sequence[str], *, also: str | None = None):
    """`value` if it is one of `choices`, else "unknown KIND VALUE; valid KINDs: ..."
    (`also` names a further valid value that is not a string, e.g. "None")."""
    if isinstance(value, str) and value in choices:
        return value
    valid = ", ".join(([also] if also else []) + list(choices))
    kinds = kind if kind.endswith("s") else f"{kind}s"  # camera_meshes is one already.
    raise ValueError(f"unknown {kind} {value!r}; valid {kinds}: {valid}")


def check_names(kind: str, names: Iterable[str], valid: Iterable[str], *,
                own: tuple[str, Iterable[str]] | None = None) -> None:
    """Raises "unknown KIND(s) 'a', 'b'; valid KINDs: ..." for names not in `valid`, then
    "; CALLER's own arguments: ..." where `own` is (CALLER, the names it takes beside them):
    a misspelt `render_mode` passed with the task options is listed among what was meant."""
    valid = sorted(valid)
    # By their text: names of mixed types ({1: ..., "foo": ...}) do not sort as they are.
    unknown = sorted(set(names) - set(valid), key=repr)
    if unknown:
        also = ""
        if own is not None:
            caller, arguments = own
            also = f"; {caller}'s own arguments: {', '.join(sorted(set(arguments) - set(valid)))}"
        raise ValueError(f"unknown {kind}(s) {', '.join(map(repr, unknown))}; "
                         f"valid {kind}s: {', '.join(valid)}{also}")


def named_parameters(function) -> tuple[str, ...]:
    """The parameters a call to `function` can name (not self, *args or **kwargs)."""
    return tuple(name for name, parameter in inspect.signature(function).parameters.items()
                 if name != "self" and parameter.kind in (parameter.POSITIONAL_OR_KEYWORD,
                                                          parameter.KEYWORD_ONLY))


def repeated(values) -> list[str]:
    """The values that stand more than once in `values`, as sorted text."""
    values = list(values)
    return sorted({str(v) for v in values if values.count(v) > 1})


def check_bool(name: str, value) -> bool:
    """`value` as a bool if it is one, Python's or numpy's (not a string such as "no", nor
    a number)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ValueError(f"{spelling(name)} must be True or False, got {value!r}")


def check_number(name: str, value, *, minimum: float | None = None,
                 maximum: float | None = None, above: float | None = None,
                 integer: bool = False) -> float | int:
    """`value` as a float (an int if `integer`) if it is a finite real number (not a bool or
    a string) within the bounds: `minimum` <= value <= `maximum`, `above` < value."""
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if integer:
        real = real and isinstance(value, numbers.Integral)
    if not real or not (integer or _finite(value)):  # An int of any size is finite.
        kind = "a whole number" if integer else "a finite number"
        too_large = real and isinstance(value, numbers.Integral)  # An int past a float.
        raise ValueError(f"{spelling(name)} must be {kind}{_bounds(minimum, maximum, above)}"
                         f"{' that a 64-bit float holds' if too_large else ''}, "
                         f"got {_shown(value)}")
    if ((minimum is not None and value < minimum) or (maximum is not None and value > maximum)
            or (above is not None and value <= above)):
        raise ValueError(f"{spelling(name)} must be{_bounds(minimum, maximum, above)}, "
                         f"got {_shown(value)}")
    return int(value) if integer else float(value)


def _finite(value: numbers.Real) -> bool:
    """Whether `value` is finite as a float (an int too large for one is not)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _shown(value) -> str:
    """`value`'s repr for a message, cut short (an int's repr past 4,300 digits raises)."""
    try:
        text = repr(value)
    except ValueError:
        return "an integer of over 4,300 digits"
    return text if len(text) <= 80 else f"{text[:40]}... ({len(text)} characters)"


def check_vector(name: str, value, size: int, **bounds) -> tuple[float, ...]:
    """`value` as a tuple of `size` floats, each checked like `check_number(**bounds)`: a
    sequence or an array, in order (not a set, whose order is its own, nor a mapping, whose
    keys alone would be read)."""
    if isinstance(value, (str, bytes, AbstractSet, Mapping)) or not isinstance(value, Iterable):
        raise ValueError(f"{name} must be a sequence of {size} numbers, got {value!r}")
    items = tuple(value)
    if len(items) != size:
        raise ValueError(f"{name} must have {size} number(s), got {len(items)}: {value!r}")
    return tuple(check_number(f"{name}[{i}]", item, **bounds) for i, item in enumerate(items))


def check_path(name: str, value) -> pathlib.Path:
    """`value` as a Path if it is one or a string naming one: an int would be taken by
    `open` for a file descriptor (reading from the caller's stdin, closing its stderr), an
    empty string by pathlib for the working folder."""
    if isinstance(value, bytes):
        value = os.fsdecode(value)
    if not isinstance(value, (str, os.PathLike)):
        raise ValueError(f"{name} must be a path (a str or os.PathLike), got "
                         f"{type(value).__name__} {value!r}")
    if not os.fspath(value):
        raise ValueError(f"{name} is empty: give a path")
    return pathlib.Path(value)


def check_writable(path, *, folder: bool = False) -> pathlib.Path:
    """`path` as a Path if a file (or, with `folder`, a folder) can be written there: the
    nearest folder on the way that exists takes a new file, or an existing file can be
    written over. Found out before the work whose result would be lost to the path. A file
    is made there and removed again, since os.access says yes to root even in /proc:
    `tempfile.TemporaryFile`, unnamed where the file system allows (O_TMPFILE), so even the
    folder's modification time stays as it was. A link is followed (the file written is the
    one it points to, `atomic_files.replace_atomically`); a device, FIFO or socket is
    refused: a file put in its place would break what uses it (root may replace /dev/null)."""
    from franka_composer.atomic_files import irregular_file

    path = pathlib.Path(path)
    problem = None if folder else irregular_file(path)
    if problem is not None:
        raise ValueError(f"cannot write to {path}: {problem}")
    real = pathlib.Path(os.path.realpath(path))
    if not folder and real.exists() and not real.is_dir():
        if not os.access(real, os.W_OK):
            raise ValueError(f"cannot write to {path}: it is read-only")
        return path
    start = real if folder else real.parent
    nearest = next((ancestor for ancestor in (start, *start.parents) if ancestor.exists()),
                   pathlib.Path("."))
    if not nearest.is_dir():
        raise ValueError(f"cannot write to {path}: {nearest} is not a folder")
    try:
        with tempfile.TemporaryFile(dir=nearest):
            pass
    except OSError as error:
        raise ValueError(f"cannot write to {path}: no file can be made in {nearest} "
                         f"({error.strerror or error})") from None
    return path


def _bounds(minimum, maximum, above) -> str:
    parts = [f"{sign} {bound if isinstance(bound, int) else format(bound, 'g')}"
             for sign, bound in ((">", above), (">=", minimum), ("<=", maximum))
             if bound is not None]  # An int whole: 2147483647, not 2.14748e+09.
    return (" " + " and ".join(parts)) if parts else ""
