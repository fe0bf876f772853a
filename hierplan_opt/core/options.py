"""Solver options, declared once: kind, range, default and one line of help.

Every solver declares its own options as :class:`Option` values beside its ``solve``
function (see :func:`hierplan_opt.registry.solver`); the default of each option is the
one in the function's signature. The same declaration checks values given in Python
(:meth:`Options.check`, strict types: ``bypass="yes"`` is refused), parses values given
as text on the command line (:meth:`Options.parse`, booleans as ``true/false``,
``yes/no`` or ``on/off`` everywhere) and describes the options for ``--help`` and
``hierplan info --solvers`` (:meth:`Option.describe`). Every refusal is one line that
names the solver, the option and the allowed values.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, cast

import yaml

from hierplan_opt.core.errors import InputError, OptionError

#: Words read as booleans, wherever a boolean is given as text.
TRUE_WORDS = ("true", "yes", "on")
FALSE_WORDS = ("false", "no", "off")
#: Word for "no value" of an optional option.
NONE_WORD = "none"

KINDS = ("bool", "int", "float", "choice", "solver", "options", "any")


def parse_bool(text: str) -> bool | None:
    """``True``/``False`` for the boolean words (any case), None for anything else.

    Example
    -------
    >>> parse_bool("Yes"), parse_bool("off"), parse_bool("maybe")
    (True, False, None)
    """
    low = text.strip().lower()
    if low in TRUE_WORDS:
        return True
    if low in FALSE_WORDS:
        return False
    return None


#: The largest amount a setting stands for (2^62; more means no limit at all).
AMOUNT_CAP = float(1 << 62)


def positive_amount(text: str, what: str, scale: int = 1, unit: str = "") -> int:
    """``text`` as a positive number times ``scale``, at least 1 (settings read from
    the environment, such as memory and size limits).

    Raises :class:`InputError` with one line naming ``what`` for anything else.

    Example
    -------
    >>> positive_amount("1.5", "HIERPLAN_MAX_INPUT_MB", 1024)
    1536
    >>> positive_amount("-2", "LIMIT_GB", unit="GB")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: LIMIT_GB must be a positive number of GB, got '-2'
    """
    message = f"{what} must be a positive number{f' of {unit}' if unit else ''}, got {text!r}"
    try:
        value = float(text)
    except ValueError:
        raise InputError(message) from None
    if not math.isfinite(value) or value <= 0:
        raise InputError(message)
    return max(1, int(min(value * scale, AMOUNT_CAP)))  # beyond any machine: no cap


@dataclass(frozen=True)
class Option:
    """One solver option.

    ``kind`` is one of ``"bool"``, ``"int"``, ``"float"`` (``low <= value``, and
    ``value < high`` when ``high`` is set), ``"choice"`` (one of ``choices``),
    ``"solver"`` (a registered solver name) or ``"options"`` (a mapping of another
    solver's options, the one named by the option ``of``). ``optional`` admits None.

    Example
    -------
    >>> opt = Option("node_limit", "int", "stop after this many expansions", low=1, optional=True)
    >>> opt.describe()
    'node_limit: integer >= 1 or none (default none) -- stop after this many expansions'
    """

    name: str
    kind: str
    help: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    optional: bool = False
    of: str = ""
    default: Any = None

    def allowed(self) -> str:
        """The allowed values in words (used in every refusal)."""
        if self.kind == "bool":
            text = "true or false"
        elif self.kind == "int":
            text = f">= {self.low:g} (an integer)" if self.low is not None else "an integer"
        elif self.kind == "float":
            text = "a number" + (f" >= {self.low:g}" if self.low is not None else "")
            text += f" and < {self.high:g}" if self.high is not None else ""
        elif self.kind == "choice":
            text = "one of " + ", ".join(repr(c) for c in self.choices)
        elif self.kind == "solver":
            text = "a solver name"
        elif self.kind == "any":
            text = "any value"
        else:
            text = f"a mapping of options of the {self.of} solver"
        return text + (" or none" if self.optional else "")

    def describe(self) -> str:
        """One line: name, allowed values, default and help (for ``--help`` listings)."""
        if self.kind == "bool":
            what = "true/false"
        elif self.kind in ("int", "float"):
            what = "integer" if self.kind == "int" else "number"
            what += f" >= {self.low:g}" if self.low is not None else ""
            what += f" and < {self.high:g}" if self.high is not None else ""
        elif self.kind == "choice":
            what = "|".join(self.choices)
        elif self.kind == "solver":
            what = "solver name"
        elif self.kind == "any":
            what = "value"
        else:
            what = f"options of the {self.of} solver"
        what += " or none" if self.optional else ""
        return f"{self.name}: {what} (default {_show(self.default)}) -- {self.help}"

    def refuse(self, solver: str, value: Any) -> OptionError:
        return OptionError(f"{solver} option {self.name} must be {self.allowed()}, got {value!r}")

    def check(self, value: object, solver: str) -> Any:
        """``value`` if it is allowed, else :class:`OptionError` naming the allowed values."""
        if value is None and self.optional:
            return None
        kind = self.kind
        if kind == "any":
            return value
        if kind == "bool" and isinstance(value, bool):
            return value
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if kind in ("int", "float") and number and self._in_range(cast(float, value)):
            if kind == "float":
                return float(cast(float, value))
            if isinstance(value, int):
                return value
        if kind == "choice" and isinstance(value, str) and value in self.choices:
            return value
        if kind == "solver" and isinstance(value, str) and value:
            return value
        if kind == "options" and isinstance(value, Mapping):
            items = cast(Mapping[object, object], value)
            if all(isinstance(k, str) for k in items):
                return {str(k): v for k, v in items.items()}
        raise self.refuse(solver, value)

    def _in_range(self, value: float) -> bool:
        return (
            math.isfinite(value)
            and (self.low is None or value >= self.low)
            and (self.high is None or value < self.high)
        )

    def parse(self, text: str, solver: str) -> Any:
        """The value of ``text`` as given on the command line, checked.

        Example
        -------
        >>> Option("w", "float", "bound", low=1).parse("1.5", "ecbs")
        1.5
        >>> Option("polish", "bool", "polish").parse("abc", "ecbs")
        Traceback (most recent call last):
        ...
        hierplan_opt.core.errors.OptionError: ecbs option polish must be true or false, got 'abc'
        """
        raw = text.strip()
        if self.optional and raw.lower() in (NONE_WORD, "null", "~"):
            return None
        value: Any = raw
        if self.kind == "bool":
            value = parse_bool(raw)
        elif self.kind == "int":
            try:
                value = int(raw)
            except ValueError:
                value = None
        elif self.kind == "float":
            try:
                value = float(raw)
            except ValueError:
                value = None
        elif self.kind == "options":
            value = _yaml_mapping(raw)
        elif self.kind == "any":
            value = _yaml_scalar(raw)
        if value is None:
            raise self.refuse(solver, text)
        return self.check(value, solver)


def parse_pairs(pairs: Sequence[str], flag: str = "--set") -> dict[str, str]:
    """``["w=1.5", "bypass=false"]`` -> ``{"w": "1.5", "bypass": "false"}`` (text, unchecked).

    Dashes in names are read as underscores. The solver's declared options turn the
    texts into values before any work (:meth:`Options.parse`).

    Example
    -------
    >>> parse_pairs(["w=1.5", "disjoint-splitting=off"])
    {'w': '1.5', 'disjoint_splitting': 'off'}
    """
    out: dict[str, str] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or not key.isidentifier():
            raise OptionError(f"{flag} expects KEY=VALUE with a solver option name, got {pair!r}")
        if key in out:
            raise OptionError(f"{flag} {key} is given twice")
        if key in ("time_limit", "seed", "objective"):
            raise OptionError(f"use --{key.replace('_', '-')} instead of {flag} {key}=...")
        out[key] = text
    return out


def _yaml_mapping(text: str) -> dict[str, Any] | None:
    try:
        out = yaml.safe_load(text)
    except yaml.YAMLError:
        return None
    return out if isinstance(out, dict) else None  # type: ignore[return-value]


def _yaml_scalar(text: str) -> Any:
    try:
        out = yaml.safe_load(text) if text else ""
    except yaml.YAMLError:
        return text
    return out if isinstance(out, (bool, int, float, str)) else text


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return NONE_WORD if value is None else str(value)


class Options:
    """The declared options of one solver, in declaration order.

    Example
    -------
    >>> opts = Options([Option("w", "float", "bound", low=1, default=1.2)])
    >>> opts.check({}, "ecbs"), opts.parse({"w": "2"}, "ecbs")
    ({'w': 1.2}, {'w': 2.0})
    >>> opts.check({"v": 1}, "ecbs")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OptionError: solver 'ecbs' has no option 'v' (its options: w)
    """

    def __init__(self, options: Sequence[Option]) -> None:
        self._by_name = {o.name: o for o in options}

    def __iter__(self) -> Iterator[Option]:
        return iter(self._by_name.values())

    def __len__(self) -> int:
        return len(self._by_name)

    def names(self) -> list[str]:
        return list(self._by_name)

    def get(self, name: str, solver: str) -> Option:
        """The option called ``name``; an :class:`OptionError` names the known ones."""
        opt = self._by_name.get(name)
        if opt is None:
            known = ", ".join(self._by_name) or "none"
            raise OptionError(f"solver {solver!r} has no option {name!r} (its options: {known})")
        return opt

    def with_defaults(self, defaults: Mapping[str, Any]) -> Options:
        """A copy whose options carry ``defaults`` (from the solve function's signature)."""
        return Options([replace(o, default=defaults.get(o.name, o.default)) for o in self])

    def check(self, values: Mapping[str, Any], solver: str) -> dict[str, Any]:
        """Every option, checked, with the defaults filled in (unknown names refused)."""
        for name in values:
            self.get(name, solver)
        return {
            o.name: o.check(values[o.name], solver) if o.name in values else o.default for o in self
        }

    def parse(self, texts: Mapping[str, str], solver: str) -> dict[str, Any]:
        """Values given as text (``--set KEY=VALUE``), parsed and checked; no defaults."""
        return {name: self.get(name, solver).parse(text, solver) for name, text in texts.items()}
