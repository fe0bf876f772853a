"""Every command and snippet of the README and the docs runs (``docs_blocks.py``).

Each Markdown file gets one scratch folder (the repository's ``instances/`` and
``tests/`` linked in, ``notebooks/`` copied, ``.venv`` this interpreter's environment)
and its blocks run there in file order, so a later command can read what an earlier one
wrote, as a reader following the page would. A shell command must exit 0; a console
block must print the output it shows; a Python snippet must run without error (its
``assert`` lines are checked); a YAML instance must load. Blocks marked
``<!-- docs-test: slow -->`` run under ``pytest -m slow``.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from docs_blocks import ROOT, Block, blocks

from hierplan_opt.io import load_instance

BLOCKS = blocks()
FAST_TIMEOUT = 300
SLOW_TIMEOUT = 1800

#: Blocks known to fail, with the reason and who fixes them. Strict: once a block
#: passes, its entry must go (the test then fails as XPASS).
KNOWN_BROKEN: dict[str, str] = {}

_folders: dict[str, Path] = {}


def folder(block: Block, factory: pytest.TempPathFactory) -> Path:
    """The scratch folder of the block's Markdown file (made on first use)."""
    if block.file not in _folders:
        d = factory.mktemp(re.sub(r"\W", "_", block.file))
        (d / "instances").symlink_to(ROOT / "instances")
        (d / "tests").symlink_to(ROOT / "tests")
        shutil.copytree(ROOT / "notebooks", d / "notebooks")
        (d / ".venv").symlink_to(sys.prefix)
        for b in BLOCKS:  # files the page asks the reader to write (also under -m slow)
            if b.file == block.file and b.kind == "file":
                (d / b.note).write_text(b.text)
        _folders[block.file] = d
    return _folders[block.file]


def environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env["MPLBACKEND"] = "Agg"  # a script's figures go nowhere (no display here)
    env.pop("PYTHONPATH", None)
    return env


def run(args: list[str], cwd: Path, slow: bool) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        args,
        cwd=cwd,
        env=environment(),
        capture_output=True,
        text=True,
        timeout=SLOW_TIMEOUT if slow else FAST_TIMEOUT,
        check=False,
    )


def _params() -> list[object]:
    out = []
    for b in BLOCKS:
        if b.kind == "setup" and b.setup == "test":
            continue  # the test suite itself: .ci/run runs it (test_setup_blocks)
        if b.kind == "manual":
            continue  # listed by test_manual_blocks
        marks = [pytest.mark.slow] if b.slow else []
        if b.id in KNOWN_BROKEN:
            marks.append(pytest.mark.xfail(reason=KNOWN_BROKEN[b.id], strict=True))
        out.append(pytest.param(b, id=b.id, marks=marks))
    return out


def test_setup_blocks() -> None:
    """The README's two set-up blocks exist; ``.ci/run`` runs exactly them."""
    setup = {b.setup: b.text for b in BLOCKS if b.kind == "setup"}
    assert set(setup) == {"install", "test"}
    assert "pip install -e" in setup["install"] and "pytest" in setup["test"]
    ci = (ROOT / ".ci" / "run").read_text()
    assert "block install" in ci and "block test" in ci


def test_manual_blocks() -> None:
    """Blocks that cannot run unattended say why, and stay few."""
    manual = [b for b in BLOCKS if b.kind == "manual"]
    assert all(b.note for b in manual), [b.id for b in manual if not b.note]
    assert len(manual) <= 3, [b.id for b in manual]


def test_blocks_found() -> None:
    kinds = {b.kind for b in BLOCKS}
    assert {"python", "shell", "console", "instance", "setup"} <= kinds
    assert {b.file for b in BLOCKS} >= {"README.md", "docs/formats.md", "docs/post.md"}
    stale = set(KNOWN_BROKEN) - {b.id for b in BLOCKS}
    assert not stale, f"KNOWN_BROKEN names blocks that are gone: {stale}"


@pytest.mark.parametrize("block", _params())
def test_doc_block(block: Block, tmp_path_factory: pytest.TempPathFactory) -> None:
    d = folder(block, tmp_path_factory)
    where = f"{block.id} ({block.kind})"
    if block.kind == "file":
        assert (d / block.note).read_text() == block.text
        return
    if block.kind == "instance":
        f = d / f"block_{block.line}.yaml"
        f.write_text(block.text)
        inst = load_instance(f)
        assert inst.num_agents >= 1, where
        return
    if block.kind == "python":
        proc = run([sys.executable, "-c", block.text], d, block.slow)
        assert proc.returncode == 0, f"{where} failed:\n{proc.stdout}\n{proc.stderr}"
        return
    command = block.text
    if block.kind == "setup":
        # what .ci/run does, minus creating the environment (.venv is this one)
        parts = [p.strip() for p in command.split("&&")]
        parts = [p for p in parts if "-m venv" not in p and "pip install" not in p]
        command = " && ".join(parts)
        if not command:
            return
    proc = run(["bash", "-euo", "pipefail", "-c", command], d, block.slow)
    if block.kind == "console":
        got = [ln.strip() for ln in (proc.stdout + proc.stderr).splitlines() if ln.strip()]
        want = [re.escape(ln).replace(r"\.\.", ".*") for ln in block.expected]
        assert len(got) == len(want), f"{where}: printed\n" + "\n".join(got)
        for g, w in zip(got, want, strict=True):
            assert re.fullmatch(w, g), f"{where}: printed {g!r}, the docs show {w!r}"
        return
    tail = f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
    assert proc.returncode == 0, f"{where}: `{command}` exited {proc.returncode}:\n{tail}"
