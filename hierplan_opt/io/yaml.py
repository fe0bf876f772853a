"""YAML reading with line numbers, and small helpers for checked access to the values.

:func:`read_yaml` returns plain Python values, except that mappings are :class:`LDict`
and sequences are :class:`LList`: a ``dict`` / ``list`` that also remembers the line of
itself and of each of its entries. Error messages then name ``file:line:``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hierplan_opt.core.errors import InputError
from hierplan_opt.io.files import limits
from hierplan_opt.io.files import read_text as _read
from hierplan_opt.io.values import plain

_Base = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class LDict(dict):
    """A mapping read from YAML: ``line`` of the mapping, ``lines[key]`` of each value."""

    line: int = 0
    lines: dict[Any, int]
    key_lines: dict[Any, int]


class LList(list):
    """A sequence read from YAML: ``line`` of the sequence, ``lines[i]`` of each item."""

    line: int = 0
    lines: list[int]


class _Loader(_Base):  # type: ignore[misc, valid-type]
    """SafeLoader that builds LDict/LList and refuses duplicate keys."""


def _construct_map(loader: _Loader, node: yaml.MappingNode) -> LDict:
    loader.flatten_mapping(node)
    out = LDict()
    out.line = node.start_mark.line + 1
    out.lines = {}
    out.key_lines = {}
    for k_node, v_node in node.value:
        key = loader.construct_object(k_node, deep=True)
        kline = k_node.start_mark.line + 1
        try:
            hash(key)
        except TypeError:
            raise _KeyProblem(kline, "a mapping key must be a plain value") from None
        if key in out:
            raise _KeyProblem(kline, f"duplicate key {key!r} (first on line {out.key_lines[key]})")
        out[key] = loader.construct_object(v_node, deep=True)
        out.lines[key] = v_node.start_mark.line + 1
        out.key_lines[key] = kline
    return out


def _construct_seq(loader: _Loader, node: yaml.SequenceNode) -> LList:
    out = LList(loader.construct_object(n, deep=True) for n in node.value)
    out.line = node.start_mark.line + 1
    out.lines = [n.start_mark.line + 1 for n in node.value]
    return out


_Loader.add_constructor("tag:yaml.org,2002:map", _construct_map)
_Loader.add_constructor("tag:yaml.org,2002:seq", _construct_seq)


class _KeyProblem(Exception):
    def __init__(self, line: int, message: str) -> None:
        super().__init__(message)
        self.line = line
        self.message = message


def to_yaml(value: Any) -> str:
    """``value`` as YAML text, through :func:`~hierplan_opt.io.values.plain` (a
    non-finite float is null, never ``.inf``): keys in their order, flat lists in flow
    style.

    Example
    -------
    >>> print(to_yaml({"b": (1, float("nan")), "a": {"x": np.float64(0.5)}}), end="")
    b: [1, null]
    a: {x: 0.5}
    """
    return yaml.safe_dump(plain(value), sort_keys=False, default_flow_style=None)


def one_line(text: str) -> str:
    """Collapse whitespace (newlines included) so a message stays on one line."""
    return re.sub(r"\s+", " ", str(text)).strip()


#: Longest message text; a value quoted from a hostile file is cut to fit.
MAX_MESSAGE = 400


def clip(text: str, limit: int = MAX_MESSAGE) -> str:
    """``text`` cut to ``limit`` characters (with "...").

    Example
    -------
    >>> clip("x" * 10, 6)
    'xxx...'
    """
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_text(path: str | Path) -> str:
    """The text of ``path``: a regular file within the size limit (see
    :func:`hierplan_opt.io.files.read_text`); every problem is an :class:`InputError`."""

    return _read(path)


def read_yaml(path: str | Path, text: str | None = None) -> Any:
    """Parse a YAML (or JSON) file into LDict/LList/scalars with line numbers.

    Syntax errors become one-line :class:`InputError` messages with YAML's line.

    Example
    -------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> f = os.path.join(d, "x.yaml")
    >>> _ = open(f, "w").write("a: 1\\nb:\\n  - [1, 2]\\n")
    >>> data = read_yaml(f)
    >>> data["b"], data.lines["b"], data["b"].lines[0]
    ([[1, 2]], 3, 3)
    """
    name = str(path)
    if text is None:
        text = read_text(path)
    try:
        return _load(text, name)
    except _KeyProblem as exc:
        raise InputError(f"{name}:{exc.line}: {exc.message}") from None
    except RecursionError:
        raise InputError(f"{name}: YAML nesting is too deep") from None
    except yaml.YAMLError as exc:
        error = _yaml_error(name, exc)
    if name.lower().endswith(".json"):
        # JSON that YAML 1.1 does not read (tabs, ...): plain data, without line numbers
        check_nesting(text, name)
        try:
            return json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"{name}:{exc.lineno}: JSON syntax error: {exc.msg}") from None
        except RecursionError:
            raise InputError(f"{name}: JSON nesting is too deep") from None
    raise error


def _load(text: str, name: str) -> Any:
    """Compose, check nesting and aliases, then construct (one document)."""
    check_nesting(text, name)
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if "*" in text:  # no alias without its "*": nothing to expand otherwise
            _check_aliases(node, name)
        return loader.construct_document(node)
    finally:
        loader.dispose()


_OPEN = np.zeros(256, dtype=np.int8)
_OPEN[[ord("["), ord("{")]] = 1
_OPEN[[ord("]"), ord("}")]] = -1


def check_nesting(text: str, name: str) -> None:
    """Refuse YAML/JSON nesting deeper than the limit before a recursive parser sees it.

    A cheap upper bound comes first: bracket depth plus, per line, indentation and
    compact ``- `` / ``? `` markers. Only when it exceeds the limit are the parser's
    events counted exactly (the event parser is not recursive).
    """

    cap = limits().max_depth
    raw = text.encode("utf-8", "surrogatepass")
    flow = int(np.cumsum(_OPEN[np.frombuffer(raw, dtype=np.uint8)]).max(initial=0))
    if flow + _block_bound(text) <= cap:
        return
    depth = 0
    try:
        for event in yaml.parse(text, Loader=_Base):
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                depth += 1
                if depth > cap:
                    line = event.start_mark.line + 1 if event.start_mark else None
                    where = f"{name}:{line}" if line else name
                    raise InputError(
                        f"{where}: YAML nesting is deeper than {cap} levels; "
                        "an instance or plan file never needs that"
                    )
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                depth -= 1
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        if "nesting depth" in str(e) and mark is not None:
            # libyaml (PyYAML >= 6.0.4 bundles one with a limit of its own, about 1000)
            # refuses before the event reaching our limit is seen: deeper than both
            raise InputError(
                f"{name}:{mark.line + 1}: YAML nesting is deeper than {min(cap, 1000)} "
                "levels; an instance or plan file never needs that"
            ) from None
        # not YAML (JSON with tabs, or a syntax error the loader will report): the
        # bracket depth is all a JSON parser can recurse on
        if flow > cap:
            raise InputError(
                f"{name}: nesting is deeper than {cap} levels; an instance or plan file "
                "never needs that"
            ) from None


def _block_bound(text: str) -> int:
    """An upper bound on block nesting: the deepest indentation plus compact markers."""
    best = 0
    for m in re.finditer(r"^([ \t]*)((?:[-?:][ \t]+)*)", text, flags=re.M):
        best = max(best, len(m.group(1)) + m.group(2).count(" ") + m.group(2).count("\t"))
    return best + 1


def _check_aliases(root: yaml.Node, name: str) -> None:
    """Refuse recursive aliases and aliases that expand the document too much.

    PyYAML shares the object of an anchor between its aliases, but code that walks the
    data (printing a value in a message, iterating nested lists) sees the expanded
    tree: ten levels of ten aliases are 10^10 nodes from a 100-line file.
    """

    size: dict[int, int] = {}
    unique = 0
    state: dict[int, int] = {}  # 1 = on the stack, 2 = done
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            total = 1 + sum(size[id(c)] for c in _children(node))
            size[key] = total
            state[key] = 2
            continue
        if state.get(key) == 2:
            continue
        if state.get(key) == 1:
            line = node.start_mark.line + 1 if node.start_mark else None
            where = f"{name}:{line}" if line else name
            raise InputError(f"{where}: recursive YAML alias (a value contains itself)")
        state[key] = 1
        unique += 1
        stack.append((node, True))
        for c in _children(node):
            if state.get(id(c)) == 1:
                line = c.start_mark.line + 1 if c.start_mark else None
                where = f"{name}:{line}" if line else name
                raise InputError(f"{where}: recursive YAML alias (a value contains itself)")
            if state.get(id(c)) != 2:
                stack.append((c, False))
    lim = limits()
    bound = lim.max_alias_factor * unique + 10000
    if size[id(root)] > bound:
        raise InputError(
            f"{name}: YAML aliases expand the document to {size[id(root)]} values "
            f"(it has {unique}); refusing more than {bound} (an alias bomb?)"
        )


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    if isinstance(node, yaml.MappingNode):
        return [x for kv in node.value for x in kv]
    return []


def _yaml_error(name: str, exc: yaml.YAMLError) -> InputError:
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        line = f":{mark.line + 1}" if mark is not None else ""
        what = " ".join(x for x in (exc.context, exc.problem) if x)
        return InputError(f"{name}{line}: YAML syntax error: {one_line(what)}")
    return InputError(f"{name}: YAML error: {one_line(str(exc))}")


class Ctx:
    """Error context for one file: builds ``file:line: message`` errors.

    Example
    -------
    >>> Ctx("a.yaml").error("bad thing", 3)
    InputError('a.yaml:3: bad thing')
    """

    def __init__(self, path: str | Path) -> None:
        self.file = str(path)

    def error(self, message: str, line: int | None = None) -> InputError:
        where = f"{self.file}:{line}" if line else self.file
        return InputError(f"{where}: {clip(one_line(message))}")

    # ------------------------------------------------------------ typed access
    def mapping(self, value: Any, what: str, line: int | None) -> LDict:
        if not isinstance(value, dict):
            raise self.error(f"{what} must be a mapping, got {_describe(value)}", line)
        if not isinstance(value, LDict):  # built in code, not read from a file
            d = LDict(value)
            d.line, d.lines, d.key_lines = line or 0, {}, {}
            return d
        return value

    def sequence(self, value: Any, what: str, line: int | None) -> LList:
        if not isinstance(value, list):
            raise self.error(f"{what} must be a list, got {_describe(value)}", line)
        if not isinstance(value, LList):
            lst = LList(value)
            lst.line, lst.lines = line or 0, [line or 0] * len(value)
            return lst
        return value

    def check_keys(
        self,
        d: LDict,
        what: str,
        allowed: Iterable[str],
        required: Iterable[str] = (),
    ) -> None:
        """Refuse unknown keys (naming the allowed ones) and missing required keys."""
        allowed = list(allowed)
        for key in d:
            if key not in allowed:
                raise self.error(
                    f"unknown key {key!r} in {what} (allowed: {', '.join(allowed)})",
                    d.key_lines.get(key, d.line),
                )
        for key in required:
            if key not in d:
                raise self.error(f"{what} is missing the key {key!r}", d.line)

    def line_of(self, d: LDict | LList, key: Any) -> int | None:
        """Line of an entry (falls back to the container's line)."""
        try:
            if isinstance(d, LDict):
                return d.lines.get(key, d.line) or None
            return d.lines[key] or None
        except (AttributeError, IndexError, KeyError, TypeError):
            return getattr(d, "line", None) or None

    def integer(
        self, value: Any, what: str, line: int | None, *, minimum: int | None = None
    ) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and math.isfinite(value) and value == int(value):
                value = int(value)
            else:
                raise self.error(f"{what} must be an integer, got {_describe(value)}", line)
        if minimum is not None and value < minimum:
            raise self.error(f"{what} must be >= {minimum}, got {value}", line)
        return int(value)

    def number(
        self,
        value: Any,
        what: str,
        line: int | None,
        *,
        positive: bool = False,
        nonnegative: bool = False,
    ) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(f"{what} must be a number, got {_describe(value)}", line)
        v = float(value)
        if not math.isfinite(v):
            raise self.error(f"{what} must be a finite number, got {value!r}", line)
        if positive and v <= 0:
            raise self.error(f"{what} must be a positive number, got {value!r}", line)
        if nonnegative and v < 0:
            raise self.error(f"{what} must not be negative, got {value!r}", line)
        return v

    def string(self, value: Any, what: str, line: int | None) -> str:
        if isinstance(value, bool) or value is None or isinstance(value, (dict, list)):
            raise self.error(f"{what} must be a name, got {_describe(value)}", line)
        if isinstance(value, float) and not math.isfinite(value):
            raise self.error(f"{what} must be a name, got {value!r}", line)
        text = str(value)
        if not text.strip():
            raise self.error(f"{what} must not be empty", line)
        return text

    def boolean(self, value: Any, what: str, line: int | None) -> bool:
        if not isinstance(value, bool):
            raise self.error(f"{what} must be true or false, got {_describe(value)}", line)
        return value


def _describe(value: Any) -> str:
    if value is None:
        return "nothing (null)"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return f"a list {_short(value)}"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return repr(value)
    return repr(value)


def _short(value: Any) -> str:
    """A JSON-like text of ``value``, at most 40 characters; never walks all of it."""
    out: list[str] = []
    budget = [41]

    def emit(text: str) -> bool:
        out.append(text)
        budget[0] -= len(text)
        return budget[0] > 0

    def walk(v: Any) -> bool:
        if isinstance(v, list):
            if not emit("["):
                return False
            for i, x in enumerate(v):
                if (i and not emit(", ")) or not walk(x):
                    return False
            return emit("]")
        if isinstance(v, dict):
            if not emit("{"):
                return False
            for i, (k, x) in enumerate(v.items()):
                if (i and not emit(", ")) or not emit(f"{json.dumps(str(k))}: ") or not walk(x):
                    return False
            return emit("}")
        try:
            return emit(json.dumps(v)[:41])
        except (TypeError, ValueError):
            return emit(str(v)[:41])

    walk(value)
    text = "".join(out)
    return text if len(text) <= 40 else text[:37] + "..."


def yaml_scalar(text: str) -> str:
    """``text`` as a YAML scalar that reads back as the same string.

    Example
    -------
    >>> yaml_scalar("agent0"), yaml_scalar("yes"), yaml_scalar("a: b")
    ('agent0', '"yes"', '"a: b"')
    """
    if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\-]*", text):
        try:
            if yaml.safe_load(text) == text:
                return text
        except yaml.YAMLError:
            pass
    return json.dumps(text)
