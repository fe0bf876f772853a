"""Collect the runnable blocks of the Markdown documentation (for ``test_docs.py``).

From ``README.md``, ``docs/*.md``, ``formulations/*.md``, ``instances/README.md`` and
``notebooks/README.md``:

- ```` ```python ```` blocks: Python snippets, run as scripts;
- ```` ```bash ```` / ```` ```sh ```` blocks and untagged blocks whose every line is a
  command (``hierplan ...``, ``python ...``, ``.venv/bin/...``): shell commands, one
  test per command (``\\`` continuations joined, ``#`` comments dropped);
- untagged or ```` ```console ```` blocks whose lines start with ``$ ``: the command and
  the output it must print (``..`` matches anything);
- ```` ```yaml ```` blocks that are instances (a top-level ``graph:``, or ``map:`` /
  ``roadmap:`` with ``agents:``): loaded with ``load_instance``; a YAML block whose
  first line is a comment naming a file (``# cmp.yaml -- ...``) is written to that file,
  for the commands after it, as a reader would.

Commands that mention placeholders (``INSTANCE``, ``NAME.py``, ``[--scen FILE ...]``)
are usage synopses, not commands; other untagged blocks are pictures, tables or output.

Markers, an HTML comment on the line before the fence:

- ``<!-- docs-test: slow (why) -->``: the block runs only under ``pytest -m slow``;
- ``<!-- docs-test: manual (why) -->``: the block cannot run unattended (it starts a
  server, opens an editor); it is listed, with its reason, but not run;
- the README's ``<!-- setup:install -->`` and ``<!-- setup:test -->`` blocks are what
  ``.ci/run`` runs on a fresh machine; here the install block runs without creating the
  virtual environment (``.venv`` is this interpreter's), and the test block, the test
  suite itself, is left to ``.ci/run``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).parent.parent

SOURCES = (
    "README.md",
    "docs/*.md",
    "formulations/*.md",
    "instances/README.md",
    "notebooks/README.md",
)

_FENCE = re.compile(r"^```([A-Za-z0-9_-]*)\s*$")
_MARK = re.compile(r"<!--\s*docs-test:\s*(\w+)\b\s*([^>]*?)\s*-->")
_FILE = re.compile(r"^#\s*([\w.-]+\.ya?ml)\b")
_SETUP = re.compile(r"<!--\s*setup:(\w+)\s*-->")
_COMMAND = re.compile(r"^(hierplan|python3?|\.venv/bin/\S+|[A-Z_]+=\S+ hierplan)\b")
_PLACEHOLDER = re.compile(r"\b[A-Z][A-Z_]{2,}\b(?!=)|\[--|\.\.\.")


@dataclass(frozen=True)
class Block:
    """One runnable piece of a Markdown file."""

    file: str  # relative to the repository
    line: int  # of the command or the fence
    kind: str  # python, shell, console, instance, file, setup, manual
    text: str  # the code, one command, or the instance YAML
    expected: tuple[str, ...] = ()  # console blocks: the output lines
    slow: bool = False
    setup: str = ""  # the README set-up block's name
    note: str = ""  # a file block's file name, a manual block's reason

    @property
    def id(self) -> str:
        return f"{self.file}:{self.line}"


def _fences(text: str) -> list[tuple[int, str, list[str], str, str]]:
    """``(line, language, lines, marker, reason)`` of every fenced block."""
    out = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if m is None:
            i += 1
            continue
        start, lang = i + 1, m.group(1).lower()
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        before = " ".join(lines[max(0, i - 2) : i])
        marker = reason = ""
        if (mm := _MARK.search(before)) is not None:
            marker, reason = mm.group(1), mm.group(2).strip("() ")
        if (sm := _SETUP.search(lines[i - 1] if i else "")) is not None:
            marker = "setup:" + sm.group(1)
        out.append((start, lang, lines[i + 1 : j], marker, reason))
        i = j + 1
    return out


def _commands(lines: list[str], first: int) -> list[tuple[int, str]]:
    """Logical command lines: continuations joined, comments and blank lines dropped."""
    out: list[tuple[int, str]] = []
    buf, at = "", 0
    for k, raw in enumerate(lines):
        line = raw.rstrip()
        if not buf:
            at = first + 1 + k
        if line.endswith("\\"):
            buf += line[:-1] + " "
            continue
        buf += line
        cmd = re.sub(r"(^|\s)#.*$", "", buf).strip()
        buf = ""
        if cmd:
            out.append((at, " ".join(cmd.split())))
    return out


def blocks() -> list[Block]:
    """Every runnable block of the documentation, in file order."""
    out: list[Block] = []
    files = sorted({p for pattern in SOURCES for p in ROOT.glob(pattern)})
    for path in files:
        rel = str(path.relative_to(ROOT))
        for start, lang, lines, marker, reason in _fences(path.read_text(encoding="utf-8")):
            slow = marker == "slow"
            if marker == "manual":
                out.append(Block(rel, start, "manual", "\n".join(lines), note=reason))
                continue
            if marker and marker != "slow" and not marker.startswith("setup:"):
                raise AssertionError(f"{rel}:{start}: unknown docs-test marker {marker!r}")
            if marker.startswith("setup:"):
                cmds = _commands(lines, start)
                out += [Block(rel, n, "setup", c, setup=marker.split(":", 1)[1]) for n, c in cmds]
                continue
            if lang == "python":
                out.append(Block(rel, start, "python", "\n".join(lines), slow=slow))
            elif lang == "yaml":
                body = "\n".join(lines)
                if lines and (fm := _FILE.match(lines[0])) is not None:
                    out.append(Block(rel, start, "file", body, slow=slow, note=fm.group(1)))
                elif re.search(r"(?m)^graph:", body) or (
                    re.search(r"(?m)^(map|roadmap):", body) and re.search(r"(?m)^agents:", body)
                ):
                    out.append(Block(rel, start, "instance", body, slow=slow))
            elif lines and lines[0].startswith("$ ") and lang in ("", "console"):
                out += _console(rel, start, lines, slow)
            elif lang in ("bash", "sh", ""):
                cmds = _commands(lines, start)
                if lang == "" and (
                    not cmds
                    or any(_PLACEHOLDER.search(c) for _, c in cmds)
                    or not all(_COMMAND.match(c) for _, c in cmds)
                ):
                    continue  # a synopsis, a picture, a table, output
                runnable = [(n, c) for n, c in cmds if not _PLACEHOLDER.search(c)]
                out += [Block(rel, n, "shell", c, slow=slow) for n, c in runnable]
    return out


def _console(rel: str, start: int, lines: list[str], slow: bool) -> list[Block]:
    out = []
    cmd, n, expected = "", 0, []
    for k, line in enumerate(lines):
        if line.startswith("$ "):
            if cmd:
                out.append(Block(rel, n, "console", cmd, tuple(expected), slow))
            cmd, n, expected = line[2:].strip(), start + 1 + k, []
        elif line.strip():
            expected.append(line.strip())
    if cmd:
        out.append(Block(rel, n, "console", cmd, tuple(expected), slow))
    return out


if __name__ == "__main__":  # pragma: no cover
    for b in blocks():
        print(b.id, b.kind, "slow" if b.slow else "", (b.text.splitlines() or [""])[0][:70])
