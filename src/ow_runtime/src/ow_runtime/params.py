"""Parameter validation shared by every configuration class of the workspace.

Each node reads its private parameters once (``rospy.get_param("~")``) and each mission file once
(YAML); :class:`Params` turns that mapping into typed values. It collects every problem instead of
stopping at the first, so a user with three mistakes in a file sees all three in one message, and
suggests the nearest known key for a misspelt one::

    p = Params(raw, where="sim", error=ConfigError)
    rate = p.number("rate_hz", 100.0, low=0.0, low_inclusive=False, unit="Hz")
    name = p.string("terrain", "flat", choices=("flat", "europa"))
    p.finish()          # raises ConfigError listing every bad value and unknown key

A value that fails keeps its default so that reading can go on; :meth:`Params.finish` then raises.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping
from typing import Any


class ParameterError(ValueError):
    """A parameter mapping with bad values or unknown keys (the default error type)."""


def _bracket(low: float, high: float, low_inclusive: bool, high_inclusive: bool) -> str:
    return f"{'[' if low_inclusive else '('}{low:g}, {high:g}{']' if high_inclusive else ')'}"


def suggest(key: str, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the known key nearest ``key``, or ``""``."""
    close = difflib.get_close_matches(key, list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


class Params:
    """Typed, range-checked reads from one parameter mapping, with every problem collected.

    Args:
        values: the mapping read (None reads as empty).
        where: prefix naming the mapping in messages (``"sim"``, ``"mission"``, ``"pid/j_x"``).
        error: exception type :meth:`finish` raises (each package's ``ConfigError``).
        parent: the :class:`Params` this one is a section of; problems are reported there.

    Raises:
        error: at once, when ``values`` is not a mapping.
    """

    def __init__(
        self,
        values: Mapping[str, Any] | None,
        where: str = "",
        error: type[Exception] = ParameterError,
        parent: Params | None = None,
    ) -> None:
        if values is None:
            values = {}
        if not isinstance(values, Mapping):
            msg = f"{where or 'parameters'} must be a mapping of names to values, got {values!r}"
            raise error(msg)
        self.values = values
        self.where = where
        self.error = error
        self._root: Params = parent._root if parent is not None else self
        self._problems: list[str] = []
        self._read: set[str] = set()

    # ------------------------------------------------------------------------------ helpers
    def name(self, key: str) -> str:
        """The full name of ``key`` as messages print it (``"sim/rate_hz"``)."""
        return f"{self.where}/{key}" if self.where else key

    def problem(self, message: str) -> None:
        """Record a problem found by the caller's own checks (reported by :meth:`finish`)."""
        self._root._problems.append(message)

    @property
    def problems(self) -> list[str]:
        """Every problem recorded so far, in the order found."""
        return list(self._root._problems)

    def has(self, key: str) -> bool:
        """True when the mapping gives ``key`` (it then counts as read)."""
        self._read.add(key)
        return key in self.values

    def raw(self, key: str, default: Any = None) -> Any:
        """The value of ``key`` as given, unchecked (it counts as read)."""
        self._read.add(key)
        return self.values.get(key, default)

    # -------------------------------------------------------------------------------- reads
    def number(
        self,
        key: str,
        default: float,
        *,
        low: float = -math.inf,
        high: float = math.inf,
        low_inclusive: bool = True,
        high_inclusive: bool = True,
        unit: str = "",
    ) -> float:
        """``key`` as a finite float within the given range (``default`` when absent)."""
        value = self.raw(key, default)
        return self.check_number(
            value,
            self.name(key),
            default,
            low=low,
            high=high,
            low_inclusive=low_inclusive,
            high_inclusive=high_inclusive,
            unit=unit,
        )

    def check_number(
        self,
        value: Any,
        name: str,
        default: float,
        *,
        low: float = -math.inf,
        high: float = math.inf,
        low_inclusive: bool = True,
        high_inclusive: bool = True,
        unit: str = "",
    ) -> float:
        """``value`` (named ``name`` in messages) as a finite float within the range."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.problem(f"{name} must be a number, got {value!r}")
            return float(default)
        number = float(value)
        if not math.isfinite(number):
            self.problem(f"{name} must be finite, got {value!r}")
            return float(default)
        below = number < low if low_inclusive else number <= low
        above = number > high if high_inclusive else number >= high
        if below or above:
            suffix = f" {unit}" if unit else ""
            limits = _bracket(low, high, low_inclusive, high_inclusive)
            self.problem(f"{name} = {number:g}{suffix} is outside {limits}{suffix}")
            return float(default)
        return number

    def positive(self, key: str, default: float, unit: str = "") -> float:
        """``key`` as a finite float > 0."""
        return self.number(key, default, low=0.0, low_inclusive=False, unit=unit)

    def non_negative(self, key: str, default: float, unit: str = "") -> float:
        """``key`` as a finite float >= 0."""
        return self.number(key, default, low=0.0, unit=unit)

    def integer(
        self, key: str, default: int, *, low: float = -math.inf, high: float = math.inf
    ) -> int:
        """``key`` as an integer within [low, high] (a float with no fraction is accepted)."""
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float) or int(value) != value:
            self.problem(f"{self.name(key)} must be an integer, got {value!r}")
            return default
        if not low <= value <= high:
            limits = _bracket(low, high, True, True)
            self.problem(f"{self.name(key)} = {int(value)} is outside {limits}")
            return default
        return int(value)

    def boolean(self, key: str, default: bool) -> bool:
        """``key`` as true or false (no truthy strings or numbers)."""
        value = self.raw(key, default)
        if not isinstance(value, bool):
            self.problem(f"{self.name(key)} must be true or false, got {value!r}")
            return default
        return value

    def string(self, key: str, default: str, choices: Iterable[str] | None = None) -> str:
        """``key`` as a string, one of ``choices`` when given."""
        value = self.raw(key, default)
        if not isinstance(value, str):
            self.problem(f"{self.name(key)} must be a string, got {value!r}")
            return default
        if choices is not None:
            options = tuple(choices)
            if value not in options:
                self.problem(
                    f"{self.name(key)} = {value!r} is not one of {', '.join(options)}"
                    f"{suggest(value, options)}"
                )
                return default
        return value

    def names(self, key: str, default: Iterable[str]) -> tuple[str, ...]:
        """``key`` as a list of distinct non-empty strings."""
        fallback = tuple(default)
        value = self.raw(key, list(fallback))
        if not isinstance(value, list | tuple) or not all(isinstance(v, str) and v for v in value):
            self.problem(f"{self.name(key)} must be a list of non-empty strings, got {value!r}")
            return fallback
        if len(set(value)) != len(value):
            self.problem(f"{self.name(key)} lists a name twice: {list(value)!r}")
            return fallback
        return tuple(value)

    def section(self, key: str) -> Params:
        """The nested mapping ``key`` (empty when absent) read with the same error collection."""
        value = self.raw(key, {})
        if value is not None and not isinstance(value, Mapping):
            self.problem(f"{self.name(key)} must be a mapping, got {value!r}")
            value = {}
        return Params(value, self.name(key), self.error, parent=self)

    # ------------------------------------------------------------------------------- ending
    def check_unknown(self, extra_known: Iterable[str] = ()) -> None:
        """Record every key of this mapping that no read asked for, with the nearest known one."""
        known = self._read | set(extra_known)
        for key in self.values:
            if key not in known:
                self.problem(f"unknown key {self.name(str(key))!r}{suggest(str(key), known)}")

    def finish(self, extra_known: Iterable[str] = ()) -> None:
        """Check for unknown keys here, then raise ``error`` listing every problem, if any.

        Raises:
            error: naming each bad value and unknown key, one per line after the first.
        """
        self.check_unknown(extra_known)
        problems = self._root._problems
        if not problems:
            return
        if len(problems) == 1:
            raise self.error(problems[0])
        listing = "\n".join(f"  - {p}" for p in problems)
        msg = f"{len(problems)} problems in {self._root.where or 'the parameters'}:\n{listing}"
        raise self.error(msg)
