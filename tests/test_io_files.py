"""Safe file access (hierplan_opt.io.files): input limits, output checks, atomic writes."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from io_helpers import write

from hierplan_opt import InputError
from hierplan_opt.core.errors import OutputError
from hierplan_opt.io import load_instance
from hierplan_opt.io.files import (
    Limits,
    atomic_path,
    check_grid,
    check_output,
    check_outputs,
    input_limits,
    limits,
    read_text,
    write_text,
)
from hierplan_opt.io.yaml import read_yaml


# ---------------------------------------------------------------- reading
@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda p: os.mkfifo(p), "is a FIFO \\(named pipe\\), not a regular file"),
        (lambda p: p.symlink_to("/dev/zero"), "is a character device, not a regular file"),
        (lambda p: p.symlink_to("/dev/urandom"), "is a character device"),
        (lambda p: p.mkdir(), "is a directory, expected a file"),
        (lambda p: None, "no such file"),
        (lambda p: p.write_bytes(b"a\x00b"), "not a text file \\(it contains NUL bytes\\)"),
        (lambda p: p.write_bytes(b"\xff\xfe"), "not a text file \\(UTF-8 decoding failed"),
    ],
)
def test_read_text_refuses_what_is_not_a_text_file(tmp_path: Path, make, match: str) -> None:
    p = tmp_path / "x.yaml"
    make(p)
    with pytest.raises(InputError, match=match):
        read_text(p)


def test_size_limit_and_bom(tmp_path: Path) -> None:
    p = write(tmp_path, "a.yaml", "\ufeffa: 1\n" + "#" * 100 + "\n")
    assert read_text(p).startswith("a: 1")
    with (
        input_limits(max_bytes=50),
        pytest.raises(InputError, match="more than the input limit of 50 bytes"),
    ):
        read_text(p)
    assert limits().max_bytes == Limits().max_bytes  # restored


def test_limits_from_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("HIERPLAN_MAX_INPUT_MB", "2")
    monkeypatch.setenv("HIERPLAN_MAX_GRID_CELLS", "100")
    lim = Limits.from_environment()
    assert lim.max_bytes == 2 << 20 and lim.max_cells == 100
    monkeypatch.setenv("HIERPLAN_MAX_GRID_CELLS", "-3")
    with pytest.raises(InputError, match="HIERPLAN_MAX_GRID_CELLS must be a positive number"):
        Limits.from_environment()


def test_yaml_nesting_and_aliases(tmp_path: Path) -> None:
    deep = write(tmp_path, "deep.yaml", "a: " + "[" * 100000 + "]" * 100000 + "\n")
    with pytest.raises(InputError, match=r"deep.yaml:1: YAML nesting is deeper than 64 levels"):
        read_yaml(deep)
    block = write(tmp_path, "block.yaml", "".join(" " * i + "-\n" for i in range(100)))
    with pytest.raises(InputError, match="block.yaml:65: YAML nesting is deeper"):
        read_yaml(block)
    ok = write(tmp_path, "ok.yaml", "a: " + "[" * 60 + "]" * 60 + "\nb: &x [1, 2]\nc: *x\n")
    assert read_yaml(ok)["c"] == [1, 2]
    rec = write(tmp_path, "rec.yaml", "a: &x [1, *x]\n")
    with pytest.raises(InputError, match="rec.yaml:1: recursive YAML alias"):
        read_yaml(rec)
    bomb = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    bomb += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 10)]
    f = write(tmp_path, "bomb.yaml", "\n".join(bomb) + "\n")
    with pytest.raises(
        InputError, match=r"aliases expand the document to 12345679021 values \(it has 31\)"
    ):
        read_yaml(f)


def test_alias_bomb_in_an_agent_name_is_refused_at_once(tmp_path: Path) -> None:
    lines = ["bombs:", "  - &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    lines += [f"  - &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9)]
    lines += ["map: {dimensions: [3, 1]}", "agents: [{name: *a8, start: [0, 0], goal: [2, 0]}]"]
    f = write(tmp_path, "x.yaml", "\n".join(lines) + "\n")
    with pytest.raises(InputError, match="alias bomb"):
        load_instance(f)


@pytest.mark.parametrize(
    ("text", "cells"),
    [
        ("map: {dimensions: [1000000000000000000000000000000, 1]}", "1e+30 cells"),
        ("graph: {dimensions: [9223372036854775808, 1]}", "9.2e+18 cells"),
        ("graph: {dimensions: [1000000, 1000000]}", "1e+12 cells and would need about 455 TB"),
        ("graph: {dimensions: [100000, 100000, 100000]}", "1e+15 cells"),
    ],
)
def test_grid_sizes_estimated_before_allocating(tmp_path: Path, text: str, cells: str) -> None:
    f = write(tmp_path, "big.yaml", text + "\nagents: [{start: [0, 0], goal: [1, 0]}]\n")
    with pytest.raises(InputError, match=f"big.yaml:1: a .* grid has {re.escape(cells)}"):
        load_instance(f)


def test_map_header_size_and_cell_limit_option(tmp_path: Path) -> None:
    m = write(tmp_path, "big.map", "type octile\nheight 100000\nwidth 100000\nmap\n")
    with pytest.raises(InputError, match=r"big.map:2: a 100000x100000 grid has 10000000000 cells"):
        load_instance(m, scen=m)
    with input_limits(max_cells=10), pytest.raises(InputError, match="the limit is 10 cells"):
        check_grid([4, 3], "")
    check_grid([4, 2], "")


# ---------------------------------------------------------------- writing
def test_check_output_refusals(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    for path, match in [
        ("", "--out: the file name is empty"),
        (tmp_path / "no" / "p.yaml", "the folder .* does not exist"),
        (tmp_path / "afile" / "p.yaml", "afile is a file, not a folder"),
        (tmp_path / "afile" / "deeper" / "p.yaml", "afile is a file, not a folder"),
        (tmp_path / "p.txt", "unsupported extension '.txt' \\(use .yaml, .json\\)"),
    ]:
        with pytest.raises(OutputError, match=match):
            check_output(path, what="--out", suffixes=(".yaml", ".json"))
    with pytest.raises(OutputError, match="adir: is a directory"):
        check_output(tmp_path / "adir", what="--out")
    with pytest.raises(OutputError, match="/dev/full: is a character device; write to a regular"):
        check_output("/dev/full", what="--out")
    assert check_output(tmp_path / "p.yaml", suffixes=(".yaml",)) == tmp_path / "p.yaml"
    with pytest.raises(OutputError, match="--dot .*: the same file as --out"):
        check_outputs([("--out", tmp_path / "s.dot", None), ("--dot", tmp_path / "s.dot", None)])


def test_atomic_write_keeps_the_old_file_on_failure(tmp_path: Path) -> None:
    f = tmp_path / "plan.yaml"
    f.write_text("old\n")
    with pytest.raises(RuntimeError), atomic_path(f) as tmp:
        tmp.write_text("half")
        raise RuntimeError("interrupted")
    assert f.read_text() == "old\n" and sorted(os.listdir(tmp_path)) == ["plan.yaml"]
    write_text(f, "new\n")
    assert f.read_text() == "new\n" and sorted(os.listdir(tmp_path)) == ["plan.yaml"]
    mode = f.stat().st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o666 & ~umask


def test_write_to_a_full_disk_is_one_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OutputError, match=r"x.yaml: cannot write \(No space left on device\)"):
        write_text(tmp_path / "x.yaml", "data")
    assert os.listdir(tmp_path) == []
