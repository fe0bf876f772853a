"""README statements a new user checks first (issue 34): the bundled warehouse's robots,
the example sweep's run count, and which commands print one summary line."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

import pytest

from hierplan_opt.cli import main
from hierplan_opt.io import load_instance

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_warehouse_comment_counts_its_robots() -> None:
    m = re.search(
        r'warehouse-part1\.yaml"\)\s*# (\d+) teams: (\d+) youBots, (\d+) Pioneers', README
    )
    assert m, "the README's comment on warehouse-part1 names its teams and robots"
    inst = load_instance(ROOT / "instances" / "paper" / "warehouse-part1.yaml")
    kinds = Counter(a.kinematics.robot_type for a in inst.agents)
    assert (len(inst.teams), kinds["youbot"], kinds["pioneer"]) == tuple(map(int, m.groups()))


def test_example_sweep_has_the_runs_the_readme_counts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    block = README.split("# cmp.yaml -- relative paths are taken from the spec's folder\n")[1]
    spec = block.split("```")[0]
    (tmp_path / "cmp.yaml").write_text(spec.replace("instances/", f"{ROOT}/instances/"))
    assert main(["sweep", str(tmp_path / "cmp.yaml"), "--dry-run"]) == 0
    runs = int(re.search(r": (\d+) runs,", capsys.readouterr().out).group(1))  # type: ignore[union-attr]
    stated = {int(n) for n in re.findall(r"sweep of (\d+) runs", README)}
    stated |= {
        int(n) for n in re.findall(r"(\d+) runs, as\s+`hierplan sweep cmp.yaml --dry-run`", README)
    }
    assert stated == {runs}, (stated, runs)


def test_summary_line_claim_matches_the_commands(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = " ".join(README.split())
    assert "Every command prints one summary line" not in text
    assert "`simulate` and `run` print a short report" in text
    part1 = str(ROOT / "instances" / "paper" / "warehouse-part1.yaml")
    plan, sched = tmp_path / "p.yaml", tmp_path / "s.yaml"
    one_line = [
        ["solve", part1, "--solver", "cbm", "--out", str(plan)],
        ["validate", part1, str(plan)],
        ["post", part1, str(plan), "--out", str(sched)],
    ]
    for argv in one_line:
        assert main(argv) == 0
        assert len(capsys.readouterr().out.splitlines()) == 1, argv[0]
    assert main(["simulate", part1, str(sched), "--out", str(tmp_path / "r.yaml")]) == 0
    assert len(capsys.readouterr().out.splitlines()) > 1  # a report, as the README says
