"""What each field of a typed document accepts, declared on the field, and the check that
reads it.

A field made with ``bounded(default, gt=, ge=, lt=, le=)`` carries its range in the dataclass
field's metadata. The bounds apply to a number, to every entry of a tuple (nested tuples too)
and to every number of a nested dataclass (both ends of a `config.Range`); None passes (an
optional field's "off"), and ``bounded(default)`` with no bound declares "any finite number"
(typed_yaml already refuses NaN and infinity). Relations between fields live in a method
``relations(self)`` of the dataclass that returns (field, holds, what it must be) triples; they
are read only once every field is within its bounds.

`typed_yaml` calls `violations` on every dataclass it builds, so a value outside its range
stops loading with the file, the field's dotted path and the reason; `check` does the same
for a dataclass built in code (``dataclasses.replace``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import typing
from dataclasses import dataclass
from typing import Any

BOUNDS_KEY = "bounds"
# the largest seed a field accepts: a 32-bit unsigned integer, what every seeded library takes
SEED_MAX = 2**32 - 1


@dataclass(frozen=True)
class Bounds:
    """An interval of the real line: each end open (gt, lt), closed (ge, le) or absent."""

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None

    def holds(self, x: float) -> bool:
        """Whether the number ``x`` lies in the interval."""
        return ((self.gt is None or x > self.gt) and (self.ge is None or x >= self.ge)
                and (self.lt is None or x < self.lt) and (self.le is None or x <= self.le))

    @property
    def bounded(self) -> bool:
        """Whether any end is given (else: any finite number)."""
        return any(v is not None for v in (self.gt, self.ge, self.lt, self.le))

    def describe(self) -> str:
        """The interval in words: "positive", "at least 1", "in (0, 1]"."""
        low = ("(", self.gt) if self.gt is not None else ("[", self.ge)
        high = (")", self.lt) if self.lt is not None else ("]", self.le)
        if low[1] is not None and high[1] is not None:
            return f"in {low[0]}{low[1]:g}, {high[1]:g}{high[0]}"
        if self.gt == 0:
            return "positive"
        if self.ge == 0:
            return "non-negative"
        if low[1] is not None:
            return f"{'above' if low[0] == '(' else 'at least'} {low[1]:g}"
        if high[1] is not None:
            return f"{'below' if high[0] == ')' else 'at most'} {high[1]:g}"
        return "a finite number"


def bounded(default: Any = dataclasses.MISSING, *, gt: float | None = None,
            ge: float | None = None, lt: float | None = None, le: float | None = None) -> Any:
    """A dataclass field with ``default`` (absent: a required field) whose numbers must lie
    within the given bounds."""
    return dataclasses.field(default=default,
                             metadata={BOUNDS_KEY: Bounds(gt=gt, ge=ge, lt=lt, le=le)})


def field_bounds(f: dataclasses.Field) -> Bounds | None:
    """The bounds declared on a dataclass field, or None."""
    return f.metadata.get(BOUNDS_KEY)


def numbers(value: Any):
    """Every int or float inside ``value`` (tuples, lists and dataclasses walked; bools,
    strings and None skipped)."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return
    if isinstance(value, int | float):
        yield value
    elif isinstance(value, tuple | list):
        for item in value:
            yield from numbers(item)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            yield from numbers(getattr(value, f.name))


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


@functools.cache
def _hints(cls: type) -> dict:
    return typing.get_type_hints(cls)


def _wrong_scalar_type(tp: Any, value: Any) -> str | None:
    """Why ``value`` cannot be a field of the plain type ``tp`` (int, float, bool), or None
    (other types are typed_yaml's to check on loading)."""
    if tp is bool and not isinstance(value, bool):
        return "must be true or false"
    if tp is int and (isinstance(value, bool) or not isinstance(value, int)):
        return "must be an integer"
    if tp is float and (isinstance(value, bool) or not isinstance(value, int | float)):
        return "must be a number"
    return None


def violations(obj: Any) -> list[tuple[str, str]]:
    """(field name, reason) for each field of the dataclass instance ``obj`` of the wrong
    plain type (int, float, bool: a dataclass built in code) or outside its bounds; if there
    are none, for each of its relations that does not hold. Nested dataclasses are not entered
    (typed_yaml and `check` visit them on their own)."""
    out = []
    hints = _hints(type(obj))
    for f in dataclasses.fields(obj):
        bounds = field_bounds(f)
        value = getattr(obj, f.name)
        wrong = _wrong_scalar_type(hints.get(f.name), value)
        if wrong is not None:
            out.append((f.name, f"{wrong}, got {_describe(value)}"))
        elif bounds is not None and not all(
                math.isfinite(x) and bounds.holds(x) for x in numbers(value)):
            out.append((f.name, f"must be {bounds.describe()}, got {_describe(value)}"))
    if out or not hasattr(obj, "relations"):
        return out
    return [(name, f"must be {what}, got {_describe(_value(obj, name))}")
            for name, holds, what in obj.relations() if not holds]


def _value(obj: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


def check(obj: Any, file: str, error_cls: type[Exception], prefix: str = "") -> None:
    """Raises ``error_cls(file, field, reason)`` for the first violation in the dataclass
    instance ``obj`` or in any dataclass nested in it (inner ones first), the field named by
    its dotted path under ``prefix``."""
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            check(value, file, error_cls, f"{prefix}.{f.name}" if prefix else f.name)
    for name, reason in violations(obj)[:1]:
        raise error_cls(file, f"{prefix}.{name}" if prefix else name, reason)
