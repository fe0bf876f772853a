"""Sweeps: specs, one process per run, limits, the SQLite store, resume, reports, CLI.

Each run is a real child process (about 0.5-1 s each for start-up and imports), so the
sweeps here are small: tiny grids, a handful of runs.
"""

from __future__ import annotations

import io
import json
import logging
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.progress import Progress
from hierplan_opt.experiments import data, reports, runner, store, worker
from hierplan_opt.experiments.spec import load_spec, parse_spec
from hierplan_opt.experiments.sweeps import plan_runs, sweep

ROOT = Path(__file__).resolve().parents[1]
MOVINGAI = ROOT / "instances" / "movingai"

# A solver of the test's own, loaded by the worker processes from PYTHONPATH: each
# `mode` misbehaves in one way.
PLUGIN = """
import os, time
from hierplan_opt.core.result import Result, Status

def solve(instance, *, time_limit=None, seed=0, objective="soc", mode="ok", fail_from=0):
    if mode == "hog":  # touch memory until the address-space limit stops us
        chunks = []
        while True:
            chunks.append(bytearray(64 * 2**20))
    if mode == "hog_hang":  # fill the address space, keep it, hang (past the hard limit)
        chunks = []
        try:
            while True:
                chunks.append(bytearray(16 * 2**20))
        except MemoryError:
            time.sleep(120)
    if mode == "numpy_hog":
        import numpy
        numpy.ones(2**38)
    if mode == "abort":
        os.abort()
    if mode == "raise":
        raise RuntimeError("bug in the solver")
    if mode == "sleep":  # ignores its time limit
        time.sleep(120)
    if fail_from and instance.num_agents >= fail_from:
        return Result(Status.TIME_LIMIT, None, lower_bound=1)
    from hierplan_opt.search.cbs import solve as cbs
    return cbs(instance, time_limit=time_limit, seed=seed, objective=objective)
"""


@pytest.fixture
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    (tmp_path / "sweep_plugin.py").write_text(PLUGIN)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    return "sweep_plugin:solve"


def empty8(agents: list[int]) -> dict:
    return {
        "map": str(MOVINGAI / "empty-8-8.map"),
        "scen": str(MOVINGAI / "empty-8-8-even-1.scen"),
        "agents": agents,
    }


def write_spec(folder: Path, text: str, name: str = "spec.yaml") -> Path:
    p = folder / name
    p.write_text(textwrap.dedent(text))
    return p


# ------------------------------------------------------------------ specs
BAD_SPECS = [
    ("solvers: [{name: cbs}]\n", r"spec.yaml:1: the sweep spec is missing the key 'instances'"),
    (
        "solvers: [{name: nope}]\ninstances: [{generator: random_grid}]\n",
        r"spec.yaml:1: solvers\[0\].name: unknown solver 'nope' \(known: .*cbs.*\)",
    ),
    (
        "solvers:\n  - {name: ecbs, options: {x: 1}}\ninstances: [{generator: random_grid}]\n",
        r"spec.yaml:2: solvers\[0\].options: solver 'ecbs' has no option 'x' \(its options: w",
    ),
    (
        "solvers: [{name: cbs}]\ninstances:\n  - {map: nowhere.map, scen: x.scen}\n",
        r"spec.yaml:3: instances\[0\].map: no such file: .*nowhere.map",
    ),
    (
        "solvers: [{name: cbs}]\ninstances: [{generator: random_grid}]\nagents: [2, -1]\n",
        r"spec.yaml:3: agents\[1\] must be >= 1, got -1",
    ),
    (
        "solvers: [{name: cbs}]\ninstances: [{generator: random_grid}]\ntime_limit: 0\n",
        r"spec.yaml:3: time_limit must be a positive number, got 0",
    ),
    (
        "solvers: [{name: cbs}]\ninstances: [{generator: random_grid}]\nmemory_limit_mb: 10\n",
        r"spec.yaml:3: memory_limit_mb must be at least 512",
    ),
    (
        "solvers: [{name: cbs}]\ninstances: [{generator: random_grid}]\nseedz: [1]\n",
        r"spec.yaml:3: unknown key 'seedz' in the sweep spec \(allowed: name, solvers",
    ),
    (
        "solvers: [{name: cbs}, {name: cbs}]\ninstances: [{generator: random_grid}]\n",
        r"spec.yaml:1: solvers\[1\]: label 'cbs' is already used",
    ),
    (
        "solvers: [{name: cbs}]\ninstances: [{generator: maze, params: {}}]\n",
        r"spec.yaml:2: instances\[0\].generator: unknown generator 'maze' \(known: random_grid",
    ),
    (
        "solvers: [{name: cbs}]\ninstances:\n  - {generator: random_grid, params: {size: 3}}\n",
        r"spec.yaml:3: instances\[0\].params: generator 'random_grid' has no parameter 'size'",
    ),
    (
        "solvers: [{name: cbm, objective: soc}]\ninstances: [{generator: random_grid}]\n",
        r"spec.yaml:1: solvers\[0\]: solver 'cbm' does not optimise 'soc'",
    ),
    ("solvers: [{name: cbs}\n", r"spec.yaml:2: YAML syntax error"),
    ("- 1\n", r"spec.yaml:1: a sweep spec must be a mapping, got a list"),
]


@pytest.mark.parametrize(("text", "message"), BAD_SPECS)
def test_bad_specs_are_refused_with_one_line(tmp_path: Path, text: str, message: str) -> None:
    p = write_spec(tmp_path, text)
    with pytest.raises(InputError, match=message) as err:
        load_spec(p)
    assert "\n" not in str(err.value)


def test_bad_agent_count_is_refused_before_any_run(tmp_path: Path) -> None:
    spec = parse_spec(
        {"solvers": [{"name": "cbs"}], "instances": [empty8([2, 5000])]}, folder=tmp_path
    )
    with pytest.raises(InputError, match=r"<spec>: instance 'empty-8-8-even-1' with 5000 agents: "
                       r".*empty-8-8-even-1.scen.*5000"):  # fmt: skip
        sweep(spec, db=tmp_path / "r.sqlite", progress=False)
    assert not (tmp_path / "r.sqlite").exists()
    tapf = write_spec(
        tmp_path,
        f"solvers: [{{name: cbm}}]\ninstances: [{{yaml: {ROOT}/instances/paper/figure3.yaml}}]\n"
        "agents: [10, 20, 30]\n",
    )
    message = (
        r"spec.yaml: instance 'figure3' with 30 agents: .*only to MAPF instances .*"
        r"\(use 'agents: all' on a TAPF instance\)$"
    )
    with pytest.raises(InputError, match=message):
        sweep(tapf, progress=False)


def test_cli_bad_spec_one_line_exit_2(tmp_path: Path) -> None:
    p = write_spec(tmp_path, "solvers: [{name: cbs}]\ninstances: []\n")
    proc = subprocess.run(
        [sys.executable, "-m", "hierplan_opt", "sweep", str(p)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert "spec.yaml:2: instances must list at least one instance" in proc.stderr


def test_spec_paths_globs_and_defaults(tmp_path: Path) -> None:
    (tmp_path / "maps").mkdir()
    for f in ("empty-8-8.map", "empty-8-8-even-1.scen", "empty-16-16-even-1.scen"):
        (tmp_path / "maps" / f).write_bytes((MOVINGAI / f).read_bytes())
    p = write_spec(
        tmp_path,
        """\
        solvers: [{name: ecbs, options: {w: 1.5}, time_limit: 5}, {name: cbs}]
        instances:
          - {map: maps/empty-8-8.map, scen: "maps/empty-*-even-1.scen", agents: [3]}
          - {generator: random_grid, params: {width: 5, height: 5}}
        agents: [2, 4]
        seeds: [0, 1]
        """,
    )
    spec = load_spec(p)
    assert [i.name for i in spec.instances] == [
        "empty-16-16-even-1",
        "empty-8-8-even-1",
        "random_grid(height=5,width=5)",
    ]
    assert spec.db == tmp_path / "spec.sqlite" and spec.memory_limit_mb == 4000
    runs = plan_runs(spec)
    # 2 scenarios x K=3 + generator x K in (2, 4); x 2 solvers x 2 seeds
    assert len(runs) == (2 + 2) * 2 * 2 and len({r.key for r in runs}) == len(runs)
    assert [r.agents for r in runs] == sorted(r.agents or 0 for r in runs)
    assert {r.time_limit for r in runs if r.solver.name == "ecbs"} == {5.0}
    assert {r.time_limit for r in runs if r.solver.name == "cbs"} == {60.0}


# ------------------------------------------------------------------ sweeping
def test_sweep_records_every_column_and_reuses_finished_runs(tmp_path: Path) -> None:
    db = tmp_path / "r.sqlite"
    spec = {
        "solvers": [{"name": "cbs"}, {"name": "ecbs", "options": {"w": 1.5}}],
        "instances": [empty8([2, 4])],
        "time_limit": 20,
        "workers": 2,
        "db": str(db),
    }
    first = sweep(spec, progress=False)
    assert (first.total, first.ran, first.reused) == (4, 4, 0)
    assert first.statuses == {"OPTIMAL": 4}
    rows = store.rows(store.open_existing(db))
    assert {(r["label"], r["agents"]) for r in rows} == {
        (s, k) for s in ("cbs", "ecbs(w=1.5)") for k in (2, 4)
    }
    for r in rows:
        assert r["instance"] == "empty-8-8-even-1" and r["seed"] == 0
        assert r["cost"] == r["lower_bound"] and r["cost"] > 0
        assert 0 < r["runtime"] < r["wall"] < 60 and r["peak_mb"] > 10
        assert r["expanded"] is not None and r["generated"] >= r["expanded"]
        assert r["versions"]["hierplan_opt"] and r["versions"]["numpy"] and r["host"]
        assert r["options"] == ({"w": 1.5} if r["solver"] == "ecbs" else {})
        assert r["time_limit"] == 20 and r["memory_limit_mb"] == 4000
    # the same spec again runs nothing; one more agent count runs only the new runs
    again = sweep(spec, progress=False)
    assert (again.ran, again.reused) == (0, 4)
    more = sweep({**spec, "instances": [empty8([2, 4, 6])]}, progress=False)
    assert (more.ran, more.reused) == (2, 4)
    assert len(store.rows(store.open_existing(db))) == 6


def test_crash_and_memory_blowup_are_recorded_and_the_sweep_goes_on(
    tmp_path: Path, plugin: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(runner, "GRACE", 2.0)  # kill the sleeper 2 s after its 1 s limit
    modes = ["hog", "numpy_hog", "abort", "raise", "sleep", "ok"]
    spec = {
        "solvers": [
            {
                "name": "plug",
                "target": plugin,
                "label": m,
                "options": {"mode": m},
                "time_limit": 1 if m == "sleep" else 20,
            }
            for m in modes
        ],  # fmt: skip
        "instances": [empty8([2])],
        "memory_limit_mb": 600,
        "workers": 2,
        "db": str(tmp_path / "r.sqlite"),
    }
    summary = sweep(spec, progress=False)
    assert summary.total == summary.ran == len(modes)
    rows = {r["label"]: r for r in store.rows(store.open_existing(tmp_path / "r.sqlite"))}
    assert rows["hog"]["status"] == "MEMOUT" and "memory" in rows["hog"]["error"]
    assert rows["numpy_hog"]["status"] == "MEMOUT"
    assert rows["abort"]["status"] == "ERROR"
    assert "SIGABRT" in rows["abort"]["error"]
    assert rows["raise"]["status"] == "ERROR"
    assert rows["raise"]["error"] == "RuntimeError: bug in the solver"
    assert rows["sleep"]["status"] == "TIME_LIMIT" and "hard limit" in rows["sleep"]["error"]
    assert 3 <= rows["sleep"]["wall"] < 15
    assert rows["ok"]["status"] == "OPTIMAL" and rows["ok"]["cost"] == 4


@pytest.mark.parametrize("how", ["fresh", "fork"])
def test_a_run_hung_at_its_memory_limit_is_memout_at_the_hard_limit(
    plugin: str, monkeypatch: pytest.MonkeyPatch, how: str
) -> None:
    """A run that hangs at its memory limit (after a failed allocation) ran out of
    memory: MEMOUT, ended one second past its time limit (audit: TIME_LIMIT, at the
    hard limit)."""
    monkeypatch.setenv("HIERPLAN_SWEEP_WORKER", how)
    if how == "fork":
        monkeypatch.setattr(runner, "run_fresh", _no_fresh)
    monkeypatch.setattr(runner, "GRACE", 8.0)  # the hard kill: 8 s after its 1 s limit
    inst = empty8([2])
    files = {Path(inst[p]).name: Path(inst[p]).read_text() for p in ("map", "scen")}
    task = {
        "instance": {"kind": "movingai", "order": list(files), "files": files},
        "agents": 2, "seed": 0, "solver": "plug", "target": plugin, "time_limit": 1,
        "memory_limit_mb": 1500, "options": {"mode": "hog_hang"},
    }  # fmt: skip
    try:
        out = runner.run_task(task)
    finally:
        runner.close_servers()
    # ended by its own watchdog one second past its time limit, not by the hard kill
    # (whose MEMOUT says "killed at the hard limit"); the wall bound only separates the
    # two (a loaded machine delays the watchdog's poll)
    assert out["status"] == "MEMOUT" and "memory limit" in out["error"], out
    assert "hard limit" not in out["error"], out
    assert 2 <= out["wall"] < 9


def test_crash_classification() -> None:
    bad_alloc = "terminate called after throwing an instance of 'std::bad_alloc'\n"
    assert runner._crashed(-6, False, bad_alloc, 1.0, 90, 10)["status"] == "MEMOUT"
    oom = runner._crashed(-9, False, "", 1.0, 900, 10)  # the kernel's OOM killer
    assert oom["status"] == "MEMOUT" and "SIGKILL" in oom["error"]
    seg = runner._crashed(-11, False, "boom\n", 1.0, 90, 10)
    assert seg["status"] == "ERROR" and seg["error"] == "the run crashed (killed by SIGSEGV: boom)"
    assert runner._crashed(-9, True, "", 12.0, 90, 10)["status"] == "TIME_LIMIT"
    assert runner._crashed(3, False, "", 1.0, 90, 10)["error"] == "the run crashed (exit code 3)"
    # numba's kernels loaded at the memory limit: LLVM aborts (audit: was ERROR)
    for llvm in ("LLVM ERROR: Unable to allocate section memory!\n", "Buffer allocation failed\n"):
        assert runner._crashed(-6, False, llvm, 3.0, 240, 16)["status"] == "MEMOUT"
    full = runner._crashed(-9, True, "", 16.0, 240, 16, "its address space at 500 MB ...")
    assert full["status"] == "MEMOUT" and "hard limit of 16 s" in full["error"]
    assert runner.memory_full(470.0, 512) and not runner.memory_full(300.0, 512)
    assert worker.address_space_mb(os.getpid()) > 0 and worker.address_space_mb(2**22 + 1) == 0


def test_stop_on_failure_skips_larger_agent_counts(tmp_path: Path, plugin: str) -> None:
    spec = {
        "solvers": [{"name": "plug", "target": plugin, "options": {"fail_from": 3}}],
        "instances": [empty8([2, 3, 4, 5])],
        "stop_on_failure": True,
        "workers": 1,
        "db": str(tmp_path / "r.sqlite"),
    }
    summary = sweep(spec, progress=False)
    rows = {r["agents"]: r for r in store.rows(store.open_existing(tmp_path / "r.sqlite"))}
    assert rows[2]["status"] == "OPTIMAL" and rows[3]["status"] == "TIME_LIMIT"
    # K=4 may have started before K=3's result came back; K=5 had not
    assert rows[4]["status"] in ("TIME_LIMIT", "SKIPPED")
    assert rows[5]["status"] == "SKIPPED" and "failed with 3 agents" in rows[5]["error"]
    assert summary.skipped >= 1 and summary.total == 4


def test_resume_after_the_sweep_was_killed(tmp_path: Path) -> None:
    """SIGKILL a running ``hierplan sweep``: resuming runs exactly the missing runs."""
    db = tmp_path / "r.sqlite"
    spec = write_spec(
        tmp_path,
        f"""\
        solvers: [{{name: cbs}}, {{name: ecbs, options: {{w: 1.5}}}}]
        instances:
          - {{map: {MOVINGAI}/empty-8-8.map, scen: {MOVINGAI}/empty-8-8-even-1.scen}}
        agents: [2, 3, 4]
        time_limit: 20
        db: r.sqlite
        """,
    )
    cmd = [sys.executable, "-m", "hierplan_opt", "-q", "sweep", str(spec)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    n = 0
    while time.monotonic() < deadline and proc.poll() is None:
        if db.exists():
            try:
                n = sqlite3.connect(db).execute("SELECT COUNT(*) FROM runs").fetchone()[0]
            except sqlite3.OperationalError:
                n = 0  # the tables are being created
            if n >= 2:
                break
        time.sleep(0.05)
    assert proc.poll() is None, "the sweep ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    con = sqlite3.connect(db)
    before = con.execute("SELECT id, key, finished_at FROM runs ORDER BY id").fetchall()
    con.close()
    assert 2 <= len(before) < 6
    time.sleep(0.5)  # the orphaned run's watchdog ends it
    res = subprocess.run(
        [sys.executable, "-m", "hierplan_opt", "-q", "sweep", "--resume", "--db", str(db)],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stderr
    assert f"({len(before)} re-used, {6 - len(before)} run, 0 skipped)" in res.stdout
    con = sqlite3.connect(db)
    after = con.execute("SELECT id, key, finished_at FROM runs ORDER BY id").fetchall()
    assert after[: len(before)] == before  # nothing lost, nothing rewritten
    assert len(after) == 6 and len({k for _, k, _ in after}) == 6  # nothing repeated
    done = con.execute("SELECT COUNT(*) FROM sweeps WHERE finished_at IS NOT NULL").fetchone()
    assert done == (1,)


# ------------------------------------------------------------------ reports
def _fake_db(path: Path) -> Path:
    con = store.connect(path)
    runs = [  # label, instance, K, status, cost, lb, runtime
        ("cbs", "a", 10, "OPTIMAL", 100, 100, 1.0),
        ("cbs", "b", 10, "OPTIMAL", 90, 90, 3.0),
        ("cbs", "a", 20, "TIME_LIMIT", None, 180, 10.0),
        ("cbs", "b", 20, "OPTIMAL", 200, 200, 5.0),
        ("ecbs", "a", 10, "FEASIBLE", 110, 95, 0.5),
        ("ecbs", "b", 10, "FEASIBLE", 99, 90, 0.2),
        ("ecbs", "a", 20, "FEASIBLE", 198, 170, 0.4),
        ("ecbs", "b", 20, "MEMOUT", None, None, 2.0),
    ]
    for i, (label, inst, k, status, cost, lb, rt) in enumerate(runs):
        store.insert_run(
            con,
            {"key": str(i), "solver": label, "label": label, "instance": inst, "agents": k,
             "seed": 0, "objective": "soc", "status": status, "cost": cost, "lower_bound": lb,
             "runtime": rt, "time_limit": 10.0},
        )  # fmt: skip
    con.close()
    return path


def test_report_tables(tmp_path: Path) -> None:
    df = reports.read_runs(_fake_db(tmp_path / "r.sqlite"))
    succ = reports.success_table(df)
    assert succ.loc["cbs", 10] == 1.0 and succ.loc["cbs", 20] == 0.5
    assert succ.loc["ecbs", 20] == 0.5
    rt = reports.runtime_table(df)
    assert rt.loc["cbs", "solved"] == 3 and rt.loc["cbs", "median"] == 3.0
    assert rt.loc["cbs", "PAR2"] == pytest.approx((1 + 3 + 20 + 5) / 4)
    assert rt.loc["ecbs", "PAR2"] == pytest.approx((0.5 + 0.2 + 0.4 + 20) / 4)
    cost = reports.cost_table(df)
    assert cost.loc["cbs", "optimal"] == 3 and cost.loc["cbs", "cost/LB max"] == 1.0
    # ecbs on a/20: 198 over its own bound 170, over the best bound (cbs proved 180)
    assert cost.loc["ecbs", "cost/LB max"] == pytest.approx(198 / 170)
    assert cost.loc["ecbs", "cost/best LB max"] == pytest.approx(max(110 / 100, 99 / 90, 198 / 180))
    text = reports.report(tmp_path / "r.sqlite")
    assert "8 runs of 2 solvers on 2 instances" in text and "50%" in text and "PAR2" in text


def test_report_figures_are_figures_without_pyplot(tmp_path: Path) -> None:
    import matplotlib

    backend = matplotlib.get_backend()
    df = reports.read_runs(_fake_db(tmp_path / "r.sqlite"))
    fig = reports.success_rate_figure(df)
    lines = fig.axes[0].get_lines()
    assert [ln.get_label() for ln in lines] == ["cbs", "ecbs"]
    assert list(lines[0].get_ydata()) == [100.0, 50.0]
    cactus = reports.cactus_figure(df)
    steps = {ln.get_label(): ln for ln in cactus.axes[0].get_lines()}
    assert list(steps["cbs"].get_xdata()) == [1.0, 3.0, 5.0]
    paths = reports.save_figures(tmp_path / "r.sqlite", tmp_path / "plots")
    assert [p.read_bytes()[:4] for p in paths] == [b"\x89PNG"] * 3
    assert matplotlib.get_backend() == backend


def test_export_csv_and_parquet(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import csv

    import pandas as pd

    db = _fake_db(tmp_path / "r.sqlite")
    assert reports.export(db, tmp_path / "r.csv") == 8
    with open(tmp_path / "r.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows][:3] == ["OPTIMAL", "OPTIMAL", "TIME_LIMIT"]
    assert list(rows[0]) == list(store.NAMES)
    assert reports.export(db, tmp_path / "r.parquet") == 8
    back = pd.read_parquet(tmp_path / "r.parquet")
    assert list(back.columns) == list(store.NAMES) and back["cost"].sum() == 797
    with pytest.raises(InputError, match=r"r.txt: export writes .csv or .parquet"):
        reports.export(db, tmp_path / "r.txt")
    monkeypatch.setattr(reports.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(InputError, match=r"pip install 'hierplan_opt\[parquet\]'"):
        reports.export(db, tmp_path / "s.parquet")
    assert not (tmp_path / "s.parquet").exists()


def test_cli_report_export_and_canned(tmp_path: Path) -> None:
    from hierplan_opt.cli import main

    db = _fake_db(tmp_path / "r.sqlite")
    assert main(["sweep", "report", str(db), "--plots", str(tmp_path / "p")]) == 0
    assert (tmp_path / "p" / "cactus.png").exists()
    assert main(["sweep", "export", str(db), str(tmp_path / "r.csv")]) == 0
    assert main(["sweep", "report", str(tmp_path / "missing.sqlite")]) == 2
    (tmp_path / "x.sqlite").write_text("not a database")
    assert main(["sweep", "report", str(tmp_path / "x.sqlite")]) == 2
    assert main(["sweep", "--canned", "nope"]) == 2
    assert main(["sweep", "--resume", "--db", str(tmp_path / "none.sqlite")]) == 2


def test_post_stage_sweep_records_the_schedule_and_reports_its_statistics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """MAPF-POST as a sweep (the canned post specs): every run plans, post-processes and
    replays; the sizes recorded are those of postprocess on the same plan."""
    import hierplan_opt
    from hierplan_opt.cli import main
    from hierplan_opt.io import load_instance
    from hierplan_opt.schedule import postprocess

    target = "hierplan_opt.experiments.stages:post"
    spec = {
        "solvers": [
            {"name": "post", "target": target, "label": "graph", "options": {"method": "graph"}},
            {"name": "post", "target": target, "label": "lp", "options": {"planner": "cbs"}},
        ],
        "instances": [empty8([3, 5])],
        "time_limit": 30,
        "db": str(tmp_path / "post.sqlite"),
    }
    summary = sweep(spec, progress=False)
    assert summary.ran == 4 and sum(summary.statuses.values()) == 4
    con = store.connect(tmp_path / "post.sqlite")
    rows = store.rows(con)
    con.close()
    assert len(rows) == 4 and all(r["stats"]["post_replay_ok"] for r in rows)
    for r in rows:  # the same plan (deterministic planners) post-processed here
        inst = load_instance(MOVINGAI / "empty-8-8.map", scen=MOVINGAI / "empty-8-8-even-1.scen",
                             agents=r["agents"])  # fmt: skip
        planner = "cbs" if r["label"] == "lp" else "ecbs"
        assert r["stats"]["planner"] == planner
        res = hierplan_opt.solve(inst, planner, **({"w": 1.5} if planner == "ecbs" else {}))
        assert res.plan is not None and r["cost"] == res.cost
        method = "lp" if r["label"] == "lp" else "graph"
        sched = postprocess(inst, res.plan, "makespan", method=method)
        assert r["stats"]["post_stn_arcs"] == sched.stats["stn_arcs"]
        assert r["stats"]["post_makespan"] == pytest.approx(sched.makespan)
    db = str(tmp_path / "post.sqlite")
    assert main(["sweep", "report", db, "--stats", "post_stn_arcs,post_solve_time"]) == 0
    out = capsys.readouterr().out
    assert "Median post_stn_arcs of solved runs by number of agents" in out
    assert "Median post_solve_time" in out
    assert main(["sweep", "report", db, "--stats", "nope"]) == 2
    assert "no solved run recorded the statistic 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("name", sorted(data.canned_specs()))
def test_canned_specs_parse_and_find_their_instances(name: str) -> None:
    from hierplan_opt.experiments.sweeps import check_instances

    spec = load_spec(data.canned_spec(name))
    runs = plan_runs(spec, check_instances(spec))
    assert runs and data.canned_specs()[name]
    for inst in spec.instances:
        for f in inst.files:  # read from the package's data, never outside it
            assert f.resolve().is_relative_to(ROOT.resolve())


def test_instances_dir_option(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(data.ENV, str(tmp_path))
    with pytest.raises(InputError, match=r"empty-8-8.map not found in .*HIERPLAN_INSTANCES"):
        data.movingai_files("empty-8-8-even-1")
    (tmp_path / "movingai").mkdir()
    for f in ("empty-8-8.map", "empty-8-8-even-1.scen"):
        (tmp_path / "movingai" / f).write_bytes((MOVINGAI / f).read_bytes())
    assert data.movingai_files("empty-8-8-even-1")[0].parent == tmp_path / "movingai"


# ------------------------------------------------------------------ progress
class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_status_lines_bar_and_off(caplog: pytest.LogCaptureFixture) -> None:
    log_info = caplog.at_level(logging.INFO, logger="hierplan_opt.progress")
    with log_info, Progress("work", total=3, unit="runs", enabled=True, interval=0.0) as p:
        p.advance(solved=1)
        p.update(lb=431.0)
    lines = [r.getMessage() for r in caplog.records]
    assert lines[0].startswith("work: 1/3 runs, solved 1, 0:00 elapsed, ETA 0:00")
    assert lines[-1].startswith("work: 1/3 runs, solved 1, lb 431, ")
    caplog.clear()
    log_info = caplog.at_level(logging.INFO, logger="hierplan_opt.progress")
    with log_info, Progress("quiet", total=2, enabled=False) as p:
        p.advance(2)
    assert caplog.records == [] and p.completed == 2
    tty = _Tty()
    with Progress("bar", total=4, unit="runs", stream=tty) as p:
        assert p.mode == "bar"
        p.advance(3, solved=2)
    assert "3/4" in tty.getvalue() and "solved 2" in tty.getvalue()
    with Progress("search", unit="nodes", stream=tty) as p:  # open-ended: no ETA
        p.advance(50, best=12)
    assert "ETA" not in p.status_line() and p.status_line().startswith("search: 50 nodes")


def test_worker_reports_json(tmp_path: Path) -> None:
    """The worker protocol itself: task on stdin, result file with the run's fields."""
    task = {
        "key": "k",
        "solver": "cbs",
        "options": {},
        "time_limit": 10,
        "memory_limit_mb": 2000,
        "seed": 0,
        "agents": 3,
        "instance": {"kind": "generator", "name": "g", "generator": "random_grid",
                     "params": {"width": 5, "height": 5}},
        "result_path": str(tmp_path / "out.json"),
    }  # fmt: skip
    proc = subprocess.run(
        [sys.executable, "-m", "hierplan_opt.experiments.worker"],
        input=json.dumps(task),
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads((tmp_path / "out.json").read_text())
    assert out["status"] == "OPTIMAL" and out["agents"] == 3 and out["cost"] >= 3


def test_a_run_lost_by_the_backend_is_an_error_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from hierplan_opt.experiments import sweeps

    def fake(task: dict) -> dict:
        if task["agents"] == 3:
            raise RuntimeError("worker lost")
        return {"status": "OPTIMAL", "cost": 1.0, "lower_bound": 1.0, "runtime": 0.1}

    monkeypatch.setattr(sweeps, "run_task", fake)
    spec = {"solvers": [{"name": "cbs"}], "instances": [empty8([2, 3, 4])],
            "db": str(tmp_path / "r.sqlite")}  # fmt: skip
    summary = sweep(spec, progress=False)
    assert summary.statuses == {"OPTIMAL": 2, "ERROR": 1}
    rows = {r["agents"]: r for r in store.rows(store.open_existing(tmp_path / "r.sqlite"))}
    assert rows[3]["error"] == "RuntimeError: worker lost"


def test_solvers_are_paired_only_with_problems_they_solve(tmp_path: Path) -> None:
    from hierplan_opt.experiments.sweeps import check_instances

    spec = parse_spec(
        {
            "solvers": [{"name": "cbs"}, {"name": "cbm"}],
            "instances": [
                empty8([2]),
                {"yaml": str(ROOT / "instances" / "paper" / "figure3.yaml"), "agents": "all"},
                {"generator": "warehouse", "params": {"team_size": 2}, "agents": [4]},
            ],
        },
        folder=tmp_path,
    )
    problems = check_instances(spec)
    assert problems == {"empty-8-8-even-1": "mapf", "figure3": "tapf",
                        "warehouse(team_size=2)": "tapf"}  # fmt: skip
    pairs = {(r.solver.name, r.instance.name) for r in plan_runs(spec, problems)}
    assert pairs == {("cbs", "empty-8-8-even-1"), ("cbm", "empty-8-8-even-1"),
                     ("cbm", "figure3"), ("cbm", "warehouse(team_size=2)")}  # fmt: skip


# ------------------------------------------------------------------ warm workers
def _no_fresh(task, python=None):
    raise AssertionError("ran in a fresh process, not forked from the warm worker")


def test_warm_worker_rows_equal_fresh_rows(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Issue 35: runs forked from a warm worker give the rows a fresh process gives.
    spec = {
        "solvers": [{"name": "cbs"}, {"name": "eecbs", "options": {"w": 1.2}}],
        "instances": [empty8([2, 5])],
        "time_limit": 20,
        "memory_limit_mb": 3000,
        "workers": 1,
    }
    monkeypatch.setenv("HIERPLAN_SWEEP_WORKER", "fresh")
    sweep({**spec, "db": str(tmp_path / "fresh.sqlite")}, progress=False)
    monkeypatch.setenv("HIERPLAN_SWEEP_WORKER", "fork")
    monkeypatch.setattr(runner, "run_fresh", _no_fresh)
    sweep({**spec, "db": str(tmp_path / "warm.sqlite")}, progress=False)
    assert not runner._servers  # the sweep stopped its warm worker
    keys = ("label", "agents", "status", "cost", "lower_bound", "expanded", "generated")
    rows = {}
    for name in ("fresh", "warm"):
        got = store.rows(store.open_existing(tmp_path / f"{name}.sqlite"))
        rows[name] = sorted(tuple(r[k] for k in keys) for r in got)
        assert all(r["peak_mb"] > 10 and 0 < r["runtime"] < r["wall"] for r in got)
        assert all(r["versions"]["numpy"] and r["host"] for r in got)
    assert rows["warm"] == rows["fresh"] and len(rows["warm"]) == 4


def test_warm_worker_keeps_limits_kills_and_crash_classes(
    tmp_path: Path, plugin: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The crash test above, every run forked from the warm worker (a limit the
    # server's address space leaves room in).
    monkeypatch.setenv("HIERPLAN_SWEEP_WORKER", "fork")
    monkeypatch.setattr(runner, "run_fresh", _no_fresh)
    monkeypatch.setattr(runner, "GRACE", 2.0)
    modes = ["hog", "numpy_hog", "abort", "raise", "sleep", "ok"]
    spec = {
        "solvers": [
            {
                "name": "plug",
                "target": plugin,
                "label": m,
                "options": {"mode": m},
                "time_limit": 1 if m == "sleep" else 20,
            }
            for m in modes
        ],  # fmt: skip
        "instances": [empty8([2])],
        "memory_limit_mb": 1500,
        "workers": 2,
        "db": str(tmp_path / "r.sqlite"),
    }
    summary = sweep(spec, progress=False)
    assert summary.total == summary.ran == len(modes)
    rows = {r["label"]: r for r in store.rows(store.open_existing(tmp_path / "r.sqlite"))}
    assert rows["hog"]["status"] == "MEMOUT" and "memory" in rows["hog"]["error"]
    assert rows["numpy_hog"]["status"] == "MEMOUT"
    assert rows["abort"]["status"] == "ERROR" and "SIGABRT" in rows["abort"]["error"]
    assert rows["raise"]["error"] == "RuntimeError: bug in the solver"
    assert rows["sleep"]["status"] == "TIME_LIMIT" and "hard limit" in rows["sleep"]["error"]
    assert 3 <= rows["sleep"]["wall"] < 15
    assert rows["ok"]["status"] == "OPTIMAL" and rows["ok"]["cost"] == 4


def test_warm_worker_hands_back_a_task_over_its_memory_limit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # A limit below the warm worker's own address space: the task runs fresh instead.
    ran = []

    def fresh(task, python=None):
        ran.append(task["memory_limit_mb"])
        return {"status": "OPTIMAL"}

    monkeypatch.setenv("HIERPLAN_SWEEP_WORKER", "fork")
    monkeypatch.setattr(runner, "run_fresh", fresh)
    mp, scen = data.movingai_files("empty-8-8-even-1")
    task = {
        "instance": {"kind": "movingai", "order": ["m.map", "s.scen"],
                     "files": {"m.map": mp.read_text(), "s.scen": scen.read_text()}},
        "agents": 2, "seed": 0, "solver": "cbs", "time_limit": 10, "memory_limit_mb": 64,
    }  # fmt: skip
    try:
        assert runner.run_task(task) == {"status": "OPTIMAL"}
        assert ran == [64]
    finally:
        runner.close_servers()


def test_a_warm_worker_that_cannot_start_is_not_retried(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("HIERPLAN_SWEEP_WORKER", "fork")
    monkeypatch.setattr(runner, "SERVE", ("-c", "raise SystemExit(1)"))
    started = []
    real = runner._Server.__init__

    def counting(self, key):
        started.append(key)
        real(self, key)

    monkeypatch.setattr(runner._Server, "__init__", counting)
    monkeypatch.setattr(runner, "run_fresh", lambda task, python=None: {"status": "OPTIMAL"})
    try:
        for _ in range(3):
            assert runner.run_task({"time_limit": 5}) == {"status": "OPTIMAL"}
        assert len(started) == 1 and started[0] in runner._failed
    finally:
        runner.close_servers()
        runner._failed.clear()


def test_worker_records_a_search_stopped_at_its_memory_limit_as_memout(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A search that stopped itself near the memory limit (core.timer.MEMORY_MARGIN) is a
    MEMOUT row, with the lower bound it proved; a plain time-out stays TIME_LIMIT."""
    from hierplan_opt.core.result import Result, Status

    stats = {"stopped_by": "memory_limit", "reason": "CBS stopped at the memory limit"}
    task = {
        "solver": "cbs", "time_limit": 10, "seed": 0, "agents": 3,
        "instance": {"kind": "generator", "name": "g", "generator": "random_grid",
                     "params": {"width": 5, "height": 5}},
    }  # fmt: skip
    given = Result(Status.TIME_LIMIT, None, lower_bound=7, stats=stats)
    monkeypatch.setattr(worker, "solve", lambda *a, **k: given)
    out = worker.solve_task(task)
    assert out["status"] == "MEMOUT" and out["lower_bound"] == 7
    assert out["stats"]["reason"].startswith("CBS stopped")
    monkeypatch.setattr(worker, "solve", lambda *a, **k: Result(Status.TIME_LIMIT, None))
    assert worker.solve_task(task)["status"] == "TIME_LIMIT"
