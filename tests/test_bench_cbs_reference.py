"""``hierplan bench cbs --reference``: the issue-22 reference set and its table."""

from __future__ import annotations

import os
import stat

import pytest

from hierplan_opt.bench import cbs as bench
from hierplan_opt.bench import scenario
from hierplan_opt.core.errors import InputError


def test_reference_set_is_shipped_complete() -> None:
    ref = bench.reference_table()
    assert len(ref) == 31
    for name, row in ref.items():
        stem, k = name.split(":")
        _, inst = scenario(name)  # map and scenario are in the package data
        assert inst.num_agents == int(k)
        if row["optimal_soc"] is not None:
            assert row["optimal_soc"] == row["lower_bound"]
            assert inst.soc_lower_bound() <= row["optimal_soc"]
    assert set(bench.REFERENCE_QUICK) <= set(ref)


def test_reference_row_checks_the_optimum(capsys) -> None:
    assert bench.main(["--reference", "--instance", "empty-8-8-even-1:16"]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("empty-8-8-even-1:16"))
    assert row.split()[1:3] == ["74", "solved"]
    assert "solved ours 1/1, CBSH2-RTC 1/1 (recorded)" in out
    assert "optima differing from the known ones: 0" in out


def test_reference_refuses_unknown_instance() -> None:
    with pytest.raises(InputError, match="not a reference instance"):
        bench.main(["--reference", "--instance", "empty-8-8-even-1:3"])


HEADER = "runtime,#high-level expanded,#high-level generated,#low-level expanded,solution cost"


def _anchor_row(tmp_path, capsys, script: str) -> tuple[list[str], str]:
    """Run the reference bench on empty-8-8 k16 beside a shell-script stand-in for the
    C++ binary (``script`` ends by writing the statistics file ``$2``): row columns, output."""
    if os.name != "posix":  # pragma: no cover
        pytest.skip("shell script stand-in")
    fake = tmp_path / "cbs"
    fake.write_text("#!/bin/sh\n" + script)
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    argv = ["--reference", "--instance", "empty-8-8-even-1:16", "--anchor", str(fake)]
    assert bench.main(argv) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("empty-8-8-even-1:16"))
    return row.split(), out


def test_anchor_output_is_read(tmp_path, capsys) -> None:
    # Writes the statistics row CBSH2-RTC writes (0.5 s runtime + 0.25 s preprocessing).
    cols, out = _anchor_row(
        tmp_path,
        capsys,
        'while [ "$1" != "-o" ]; do shift; done\n'
        f"printf '{HEADER},preprocessing runtime\\n0.5,7,13,99,74,0.25\\n' > \"$2\"\n",
    )
    assert cols[4] == "0.750" and cols[8] == "7/13" and cols[10] == "99"
    assert cols[6].endswith("/1")  # 0.75 s: the C++ runs once
    assert "CBSH2-RTC 1/1;" in out


def test_short_instances_are_repeated_median_reported(tmp_path, capsys, monkeypatch) -> None:
    # A stand-in that takes 10, 30 and 20 ms (its runs counted in a file): median 20 ms.
    count = tmp_path / "count"
    monkeypatch.setattr(bench, "REPEAT_MAX", 3)
    cols, out = _anchor_row(
        tmp_path,
        capsys,
        f"n=$(cat {count} 2>/dev/null || echo 0); n=$((n + 1)); echo $n > {count}\n"
        "case $n in 1) t=0.01;; 2) t=0.03;; *) t=0.02;; esac\n"
        'while [ "$1" != "-o" ]; do shift; done\n'
        f"printf '{HEADER}\\n%s,7,13,99,74\\n' $t > \"$2\"\n",
    )
    assert cols[4] == "0.0200" and cols[6] == "3/3"
    assert count.read_text().strip() == "3"
    assert "median of the runs" in out


def test_unsolved_side_runs_once(tmp_path, capsys) -> None:
    # A stand-in that gives up at once (cost -1, 1 ms): no repeats, no ratio.
    count = tmp_path / "count"
    cols, out = _anchor_row(
        tmp_path,
        capsys,
        f"n=$(cat {count} 2>/dev/null || echo 0); echo $((n + 1)) > {count}\n"
        'while [ "$1" != "-o" ]; do shift; done\n'
        f"printf '{HEADER}\\n0.001,7,13,99,-1\\n' > \"$2\"\n",
    )
    assert count.read_text().strip() == "1"
    assert cols[4] == "inf" and cols[5] == "-" and cols[6].endswith("/1")
    assert "CBSH2-RTC 0/1;" in out
