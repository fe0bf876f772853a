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


def test_reference_prints_the_bound_of_an_unsolved_instance(capsys) -> None:
    # Stopped after one CT node: TIME_LIMIT with a proven bound, printed on the closing
    # line beside CBSH2-RTC's recorded cost (it solved the instance).
    argv = ["--reference", "--instance", "empty-8-8-even-1:16", "--option", "node_limit=1"]
    assert bench.main(argv) == 0
    out = capsys.readouterr().out
    assert "solved ours 0/1, CBSH2-RTC 1/1 (recorded)" in out
    line = out.strip().splitlines()[-1]
    assert line.startswith("unsolved by a side (bound proved; cost if solved), ours/C++: ")
    name, sides = line.split(": ", 1)[1].split()
    ours, cpp = sides.split("/")
    assert name == "empty-8-8-even-1:16" and cpp == "74"
    _, inst = scenario(name)
    assert inst.soc_lower_bound() <= int(ours) <= 74


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
    assert out.strip().splitlines()[-1].endswith("ours/C++: empty-8-8-even-1:16 74/-")


def _per_process(tmp_path, capsys, stats_row: str) -> str:
    """Run the per-process bench on empty-8-8 k16 (ours a real `hierplan solve` process)
    beside a stand-in peer that writes ``stats_row`` under CBSH2-RTC's statistics header
    with ``min f value``: the output."""
    if os.name != "posix":  # pragma: no cover
        pytest.skip("shell script stand-in")
    fake = tmp_path / "peer"
    fake.write_text(
        '#!/bin/sh\nwhile [ "$1" != "-o" ]; do shift; done\n'
        f"printf '{HEADER},min f value\\n{stats_row}\\n' > \"$2\"\n"
    )
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    argv = ["--per-process", "--instance", "empty-8-8-even-1:16", "--anchor", str(fake)]
    assert bench.main(argv) == 0
    return capsys.readouterr().out


def test_per_process_runs_hierplan_solve_beside_the_peer(tmp_path, capsys) -> None:
    # The peer solves in 0.02 s (its runtime) with cost and bound 74, as CBSH2-RTC does.
    out = _per_process(tmp_path, capsys, "0.02,7,13,99,74,74")
    cols = next(ln for ln in out.splitlines() if ln.startswith("empty-8-8-even-1:16")).split()
    assert cols[1:4] == ["OPTIMAL", "74", "74"]
    assert cols[5] == "0.0200" and float(cols[4]) > 0  # the solve's own CPU seconds
    assert float(cols[7]) > float(cols[4])  # the process takes longer than its solve
    assert "solved ours 1/1, C++ 1/1" in out
    assert "optima differing from the known ones: 0" in out
    assert "unsolved by a side" not in out


def test_per_process_prints_the_bound_the_peer_proved(tmp_path, capsys) -> None:
    # The peer gives up (cost -1) with its bound 70: the closing line has our cost and it.
    out = _per_process(tmp_path, capsys, "0.02,7,13,99,-1,70")
    assert "solved ours 1/1, C++ 0/1" in out
    assert out.strip().splitlines()[-1].endswith("ours/C++: empty-8-8-even-1:16 74/70")


def test_per_process_ecbs_counts_bounded_plans(tmp_path, capsys) -> None:
    from hierplan_opt.bench import ecbs

    argv = ["--reference", "--per-process", "--instance", "empty-8-8-even-1:8"]
    assert ecbs.main(argv + ["--time-limit", "10"]) == 0
    out = capsys.readouterr().out
    assert "solved ours 1/1, C++ 0/1 (w=1.2, within the bound)" in out
    with pytest.raises(InputError, match="one solver at one w"):
        ecbs.main(argv + ["--w", "1.1,1.2"])


def test_summary_line_has_the_solve_cpu_seconds(capsys) -> None:
    from hierplan_opt.cli import main
    from hierplan_opt.experiments.data import movingai_files

    mp, scen = movingai_files("empty-8-8-even-1")
    assert main(["solve", str(mp), "--scen", str(scen), "--agents", "4"]) == 0
    d = bench.parse_summary(capsys.readouterr().out.strip().splitlines()[-1])
    assert d["status"] == "OPTIMAL" and d["cpu"].endswith("s") and float(d["cpu"][:-1]) >= 0
