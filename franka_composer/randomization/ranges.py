"""The range a randomisation distribution draws in, worked out from its structure.

Composer's distributions with constant arguments have known ranges (`Normal`'s is the real
line, `LogNormal`'s the positive half of it, `Uniform(a, b)`'s [a, b]); its noise wrappers
and `+ - * /` and negation on them combine ranges by interval arithmetic. Each end records
whether it is open (never drawn: `LogNormal`'s 0, every infinite end), so that a factor
drawn from `0.5 * LogNormal(0, 0.1)` is known to stay above 0 while one from
`Uniform(0, 1)` is not. A range that cannot be worked out (a distribution of distributions,
a variation of one's own) is None: only its draws are checked.
"""

from __future__ import annotations

import dataclasses
import numbers
import operator
from typing import Callable

import numpy as np
from dm_control.composer.variation import base, distributions, noises


def is_constant(value) -> bool:
    """Whether `value` is a constant a parameter can take: a number (Python's or numpy's),
    an array, or a sequence of numbers; not a bool."""
    return (isinstance(value, (numbers.Real, np.ndarray, tuple, list))
            and not isinstance(value, (bool, np.bool_)))


@dataclasses.dataclass(frozen=True)
class Interval:
    """Componentwise [low, high], each end open where its flag says (infinite ends are)."""

    low: np.ndarray
    high: np.ndarray
    low_open: np.ndarray
    high_open: np.ndarray

    @classmethod
    def of(cls, low, high, low_open=False, high_open=False) -> "Interval":
        # + 0.0: one zero, whichever its sign (1 / -0.0 would flip an end's side).
        low, high = np.asarray(low, np.float64) + 0.0, np.asarray(high, np.float64) + 0.0
        low, high, low_open, high_open = np.broadcast_arrays(
            low, high, np.asarray(low_open) | np.isinf(low), np.asarray(high_open) | np.isinf(high))
        return cls(low, high, low_open, high_open)

    def holds_zero(self) -> np.ndarray:
        """Componentwise, whether 0 can be drawn."""
        return (((self.low < 0) | ((self.low == 0) & ~self.low_open))
                & ((self.high > 0) | ((self.high == 0) & ~self.high_open)))

    def within(self, least: float, most: float, above_least: bool = False) -> bool:
        """Whether every draw lies in [least, most] (in (least, most] if `above_least`)."""
        low_ok = (self.low > least) | ((self.low == least) & (self.low_open | ~above_least))
        return bool(np.all(low_ok & (self.high <= most)))

    def __str__(self) -> str:
        """The whole range over the components: "[0.5, 1.5]", "(0, inf)"."""
        low, high = np.argmin(self.low), np.argmax(self.high)
        return (f"{'(' if self.low_open.flat[low] else '['}{self.low.flat[low]:g}, "
                f"{self.high.flat[high]:g}{')' if self.high_open.flat[high] else ']'}")

    def __neg__(self) -> "Interval":
        return Interval(-self.high, -self.low, self.high_open, self.low_open)

    def __add__(self, other: "Interval") -> "Interval":
        return Interval.of(self.low + other.low, self.high + other.high,
                           self.low_open | other.low_open, self.high_open | other.high_open)

    def __mul__(self, other: "Interval") -> "Interval":
        corners = []
        for value, is_open in ((self.low, self.low_open), (self.high, self.high_open)):
            for other_value, other_open in ((other.low, other.low_open),
                                            (other.high, other.high_open)):
                with np.errstate(invalid="ignore"):
                    product = value * other_value
                # 0 times an unbounded end: the products near it run through all of one
                # side, 0 among them (drawn where the 0 is).
                zero_by_inf = np.isnan(product)
                exact_zero = ((value == 0) & ~is_open) | ((other_value == 0) & ~other_open)
                corners.append((np.where(zero_by_inf, 0.0, product),
                                np.where(zero_by_inf, ~exact_zero, is_open | other_open)
                                & ~((product == 0) & exact_zero)))
        values = np.stack([value for value, _ in corners])
        opens = np.stack([is_open for _, is_open in corners])
        low, high = values.min(axis=0), values.max(axis=0)
        # An end is open unless some corner reaching it is drawn.
        low_open = np.all(opens | (values != low), axis=0)
        high_open = np.all(opens | (values != high), axis=0)
        return Interval.of(low, high, low_open, high_open)

    def reciprocal(self) -> "Interval":
        """1 / x over the interval; the whole line where 0 can be drawn."""
        if np.any(self.holds_zero()):
            return Interval.of(-np.inf, np.inf)
        with np.errstate(divide="ignore"):
            # A 0 end is open, on the side the interval lies on: its reciprocal unbounded
            # that side. 1 / an infinite end is 0, never drawn.
            low = np.where(self.high == 0, -np.inf, 1.0 / self.high)
            high = np.where(self.low == 0, np.inf, 1.0 / self.low)
        return Interval.of(low, high, self.high_open, self.low_open)


def draw_range(distribution, nominal) -> Interval | None:
    """The range `distribution`, called with `initial_value=nominal`, draws in (module
    docstring); None where it is not known."""
    if is_constant(distribution):
        return Interval.of(distribution, distribution)
    kind = type(distribution)
    if isinstance(distribution, distributions.Distribution):
        arguments = dict(zip(_ARGUMENT_NAMES.get(kind, ()), distribution._args))  # pylint: disable=protected-access
        arguments.update(distribution._kwargs)  # pylint: disable=protected-access
        if kind not in _RANGES or not all(value is None or is_constant(value)
                                          for value in arguments.values()):
            return None
        return _RANGES[kind](**arguments)
    if kind in (noises.Additive, noises.Multiplicative):
        if distribution._cumulative:  # pylint: disable=protected-access
            return None  # About the current value, which drifts.
        inner = draw_range(distribution._variation, nominal)  # pylint: disable=protected-access
        if inner is None:
            return None
        value = Interval.of(nominal, nominal)
        return value + inner if kind is noises.Additive else value * inner
    if kind is base._BinaryOperation:  # pylint: disable=protected-access
        first = draw_range(distribution._first, nominal)  # pylint: disable=protected-access
        second = draw_range(distribution._second, nominal)  # pylint: disable=protected-access
        operation = _OPERATIONS.get(distribution._op)  # pylint: disable=protected-access
        if first is None or second is None or operation is None:
            return None
        return operation(first, second)
    if kind is base._UnaryOperation and distribution._op is operator.neg:  # pylint: disable=protected-access
        inner = draw_range(distribution._variation, nominal)  # pylint: disable=protected-access
        return None if inner is None else -inner
    return None


#: The names of the arguments Composer's distributions pass positionally.
_ARGUMENT_NAMES = {distributions.UniformInteger: ("low",),
                   distributions.UniformChoice: ("choices",),
                   distributions.Bernoulli: ("prob",)}


def _uniform_integer(low, high=None) -> Interval:
    low, high = (0, low) if high is None else (low, high)
    return Interval.of(low, np.asarray(high) - 1)


#: Each distribution's range from its (constant) arguments. Uniform's high end counts as
#: drawn: numpy's may return it after rounding.
_RANGES: dict[type, Callable[..., Interval]] = {
    distributions.Uniform: lambda low, high: Interval.of(np.minimum(low, high),
                                                         np.maximum(low, high)),
    distributions.UniformInteger: _uniform_integer,
    # numpy's choice(n), n a number, draws from 0 to n - 1.
    distributions.UniformChoice: lambda choices: (
        Interval.of(0, np.asarray(choices) - 1) if np.ndim(choices) == 0
        else Interval.of(np.min(choices, axis=0), np.max(choices, axis=0))),
    distributions.Normal: lambda loc, scale: (
        Interval.of(loc, loc) if np.all(np.asarray(scale) == 0) else Interval.of(-np.inf, np.inf)),
    distributions.LogNormal: lambda mean, sigma: Interval.of(0.0, np.inf, low_open=True),
    distributions.Exponential: lambda scale: Interval.of(0.0, np.inf),
    distributions.Poisson: lambda lam: Interval.of(0.0, np.inf),
    distributions.Bernoulli: lambda prob: Interval.of(0.0, 1.0),
}

_OPERATIONS = {
    operator.add: lambda a, b: a + b,
    operator.sub: lambda a, b: a + -b,
    operator.mul: lambda a, b: a * b,
    operator.truediv: lambda a, b: a * b.reciprocal(),
}
