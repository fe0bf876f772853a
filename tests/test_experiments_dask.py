"""A sweep on a Dask cluster (two workers on loopback) gives the rows local processes give."""

from __future__ import annotations

from pathlib import Path

import pytest

from hierplan_opt.experiments import store
from hierplan_opt.experiments.sweeps import sweep

MOVINGAI = Path(__file__).resolve().parents[1] / "instances" / "movingai"
#: Columns that depend on the run, not on where it ran.
SAME = ("key", "solver", "label", "instance", "instance_hash", "agents", "seed", "status",
        "cost", "lower_bound", "expanded", "generated", "low_level_expanded")  # fmt: skip


def _spec(db: Path) -> dict:
    return {
        "solvers": [{"name": "cbs"}, {"name": "eecbs", "options": {"w": 1.2}}],
        "instances": [
            {
                "map": str(MOVINGAI / "empty-8-8.map"),
                "scen": str(MOVINGAI / "empty-8-8-even-1.scen"),
            },
            {"generator": "random_grid", "params": {"width": 6, "height": 6, "obstacles": 0.1}},
        ],
        "agents": [4],
        "time_limit": 20,
        "db": str(db),
    }


def _rows(db: Path) -> list[tuple]:
    rows = store.rows(store.open_existing(db))
    return sorted(tuple(r[c] for c in SAME) for r in rows)


def test_local_dask_cluster_gives_the_same_rows_as_local_processes(tmp_path: Path) -> None:
    from distributed import LocalCluster

    local = sweep(_spec(tmp_path / "local.sqlite"), workers=2, progress=False)
    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    ) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://127.0.0.1:")
        # the same path as `hierplan sweep SPEC --dask-scheduler tcp://HOST:PORT`
        on_dask = sweep(_spec(tmp_path / "dask.sqlite"), dask=address, progress=False)
    assert local.ran == on_dask.ran == 4
    assert _rows(tmp_path / "local.sqlite") == _rows(tmp_path / "dask.sqlite")
    assert {r[SAME.index("status")] for r in _rows(tmp_path / "dask.sqlite")} <= {
        "OPTIMAL",
        "FEASIBLE",
    }


def test_bad_scheduler_address_is_one_line(tmp_path: Path) -> None:
    from hierplan_opt.core.errors import InputError

    with pytest.raises(InputError, match=r"--dask-scheduler expects tcp://HOST:PORT"):
        sweep(_spec(tmp_path / "x.sqlite"), dask="127.0.0.1:1", progress=False)
