"""Issue 34, "Formats as they are in the wild": MAPF Tracker move strings, libMRP's own
test instances, default solvers for TAPF, lossy conversion to libMRP."""

from __future__ import annotations

from pathlib import Path

import pytest

import hierplan_opt as hp
from hierplan_opt.cli import main

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"


# ----------------------------------------------------------- default solver for TAPF
@pytest.mark.parametrize(
    ("path", "solver"),
    [
        (DATA / "tapf_lmrp.yaml", "cbm"),
        (ROOT / "instances" / "paper" / "warehouse-part1.yaml", "cbm"),
    ],
)
def test_solve_tapf_without_solver_picks_one_and_says_which(path, solver, capsys) -> None:
    code = main(["solve", str(path), "--time-limit", "20"])
    out, err = capsys.readouterr()
    assert code == 0 and out.startswith("OPTIMAL") and f"solver={solver}" in out
    assert f"using {solver} (TAPF with 2 teams)" in err


def test_solve_one_team_without_solver_uses_flow(tmp_path, capsys) -> None:
    inst = hp.Instance.tapf(hp.Graph.grid(3, 3), [([(0, 0), (2, 2)], [(0, 2), (2, 0)])])
    hp.save_instance(tmp_path / "one.yaml", inst)
    code = main(["solve", str(tmp_path / "one.yaml")])
    out, err = capsys.readouterr()
    assert code == 0 and "solver=flow" in out and "using flow (TAPF with one team)" in err


def test_solve_mapf_without_solver_still_uses_cbs(capsys) -> None:
    code = main(["solve", str(DATA / "corridor.yaml")])
    out, err = capsys.readouterr()
    assert code == 0 and "solver=cbs" in out and err == ""


# ------------------------------------------------------------ lossy convert to libMRP
def test_convert_warehouse_to_lmrp_writes_and_warns(tmp_path, capsys) -> None:
    src = ROOT / "instances" / "paper" / "warehouse-part1.yaml"
    out = tmp_path / "wh.yaml"
    code = main(["convert", str(src), "--to", "lmrp", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 0 and out.exists()
    assert "cannot hold highways" in err and "cannot hold robot kinematics" in err
    orig, back = hp.load_instance(src), hp.load_instance(out)
    assert back.highways is None and back.starts == orig.starts
    assert sorted(map(sorted, (t.targets for t in back.teams))) == sorted(
        map(sorted, (t.targets for t in orig.teams))
    )


def test_convert_plain_instance_to_lmrp_warns_nothing(tmp_path, capsys) -> None:
    code = main(
        [
            "convert",
            str(DATA / "corridor_lmrp.yaml"),
            "--to",
            "lmrp",
            "--out",
            str(tmp_path / "c.yaml"),
        ]
    )
    assert code == 0 and "warning" not in capsys.readouterr().err
