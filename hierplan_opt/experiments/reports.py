"""Reading a sweep database: the field's standard tables, plots, and CSV/Parquet export.

Tables (:func:`report` prints all three):

* **success rate vs agents** — per solver, the share of runs with a definite answer
  (OPTIMAL, FEASIBLE or INFEASIBLE) for each number of agents;
* **runtime distribution** — per solver, runs and solved runs, min / median / mean /
  90th percentile / max runtime of the solved runs, and PAR2 (the mean runtime with every
  unsolved run counted as twice its time limit);
* **cost over lower bound** — per solver, over its solved runs: how many are proven
  optimal, the median and largest cost / own lower bound, and the median and largest
  cost / best lower bound any solver proved for the same instance, K and objective;
* on request, **statistics by agents** (:func:`stats_table`) — per solver and number of
  agents, the median of a statistic the runs recorded (node counts, a stage's sizes and
  times).

Figures are matplotlib ``Figure`` objects built without pyplot (no backend is chosen
or switched): :func:`success_rate_figure` (success-rate curves against the number of
agents), :func:`runtime_figure` (median runtime against the number of agents) and
:func:`cactus_figure` (solved runs against runtime, one line per solver).
"""

from __future__ import annotations

import csv
import importlib.util
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hierplan_opt.core.errors import InputError
from hierplan_opt.experiments import store

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

SOLVED = ("OPTIMAL", "FEASIBLE", "INFEASIBLE")
#: Marker per curve, so that curves lying on top of each other stay visible.
MARKERS = "os^Dv<>PX*"


def read_runs(db: str | Path) -> pd.DataFrame:
    """Table ``runs`` of a sweep database as a pandas DataFrame (JSON columns as text),
    with a boolean column ``solved``.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.experiments import store
    >>> f = os.path.join(tempfile.mkdtemp(), "r.sqlite")
    >>> store.connect(f).close()
    >>> len(read_runs(f))
    0
    """
    import pandas as pd  # heavy module: pandas

    con = store.open_existing(db)
    try:
        df = pd.read_sql_query("SELECT * FROM runs ORDER BY id", con)
    finally:
        con.close()
    df["solved"] = df["status"].isin(SOLVED)
    return df


def _labels(df: pd.DataFrame) -> list[str]:
    return list(dict.fromkeys(df["label"]))  # first-seen order


def success_table(df: pd.DataFrame) -> pd.DataFrame:
    """Share of solved runs per solver (rows) and number of agents (columns)."""
    if df.empty:
        return df
    t = df.pivot_table(index="label", columns="agents", values="solved", aggfunc="mean")
    return t.reindex(_labels(df))


def runtime_table(df: pd.DataFrame) -> pd.DataFrame:
    """Runtime distribution of the solved runs per solver, and PAR2."""
    import pandas as pd  # heavy module: pandas

    out = []
    for label in _labels(df):
        d: Any = df[df["label"] == label]
        s: Any = d.loc[d["solved"], "runtime"].astype(float)
        par2 = d["runtime"].where(d["solved"], 2 * d["time_limit"]).astype(float).mean()
        out.append(
            {
                "solver": label,
                "runs": len(d),
                "solved": int(d["solved"].sum()),
                "min": s.min() if len(s) else math.nan,
                "median": s.median() if len(s) else math.nan,
                "mean": s.mean() if len(s) else math.nan,
                "p90": s.quantile(0.9) if len(s) else math.nan,
                "max": s.max() if len(s) else math.nan,
                "PAR2": par2,
            }
        )
    return pd.DataFrame(out).set_index("solver") if out else pd.DataFrame()


def _content(df: pd.DataFrame) -> Any:
    """Per run (a Series), its instance's name and content hash (older stores: the name
    only)."""
    names: Any = df["instance"].astype(str)
    if "instance_hash" not in df:
        return names
    return names + "#" + df["instance_hash"].fillna("").astype(str)


def cost_table(df: pd.DataFrame) -> pd.DataFrame:
    """Cost over lower bounds of the solved runs per solver."""
    import pandas as pd  # heavy module: pandas

    df = df.assign(content=_content(df))
    ok: Any = df[df["status"].isin(("OPTIMAL", "FEASIBLE")) & df["cost"].notna()].copy()
    # one instance is one content: a scenario edited between sweeps keeps its name
    group = ["content", "agents", "objective", "seed"]
    best: Any = df[df["lower_bound"].notna()].groupby(group)["lower_bound"].max()
    ok = ok.join(best.rename("best_lb"), on=group)
    ok["own"] = ok["cost"] / ok["lower_bound"].where(ok["lower_bound"] > 0)
    ok["vs_best"] = ok["cost"] / ok["best_lb"].where(ok["best_lb"] > 0)
    out = []
    for label in _labels(df):
        d: Any = ok[ok["label"] == label]
        out.append(
            {
                "solver": label,
                "solved": len(d),
                "optimal": int((d["status"] == "OPTIMAL").sum()),
                "cost/LB median": d["own"].median(),
                "cost/LB max": d["own"].max(),
                "cost/best LB median": d["vs_best"].median(),
                "cost/best LB max": d["vs_best"].max(),
            }
        )
    return pd.DataFrame(out).set_index("solver") if out else pd.DataFrame()


def stats_table(df: pd.DataFrame, key: str) -> pd.DataFrame:
    """Median of statistic ``key`` (from the runs' ``stats``) of the solved runs per
    solver (rows) and number of agents (columns); :class:`InputError` when no run
    recorded ``key`` as a number.

    Example
    -------
    >>> import pandas as pd
    >>> df = pd.DataFrame({"label": ["a", "a", "a"], "agents": [2, 2, 4],
    ...     "solved": [True, True, True], "stats": ['{"n": 3}', '{"n": 5}', '{"n": 9}']})
    >>> stats_table(df, "n").to_dict()
    {2: {'a': 4.0}, 4: {'a': 9.0}}
    """

    def value(text: Any) -> float:
        v = json.loads(text).get(key) if isinstance(text, str) and text else None
        return float(v) if isinstance(v, (int, float)) else math.nan

    d: Any = df[df["solved"]].copy()
    d["value"] = d["stats"].map(value)
    d = d[d["value"].notna()]
    if d.empty:
        raise InputError(f"no solved run recorded the statistic {key!r}")
    t = d.pivot_table(index="label", columns="agents", values="value", aggfunc="median")
    return t.reindex([x for x in _labels(df) if x in t.index])


def _number(v: float) -> str:
    """A count as an integer, anything else with four significant digits."""
    return f"{v:.0f}" if math.isfinite(v) and v == int(v) else f"{v:.4g}"


def report(db: str | Path, stats: list[str] | tuple[str, ...] = ()) -> str:
    """The three standard tables of a sweep database as text (and with ``stats``, the
    median of each of those run statistics by solver and agents).

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.experiments import store
    >>> f = os.path.join(tempfile.mkdtemp(), "r.sqlite")
    >>> store.connect(f).close()
    >>> report(f)
    'no runs recorded in ...r.sqlite'
    """
    df = read_runs(db)
    if df.empty:
        return f"no runs recorded in {db}"
    statuses = df["status"].value_counts()
    head = (
        f"{len(df)} runs of {df['label'].nunique()} solvers on {_content(df).nunique()} "
        f"instances: " + ", ".join(f"{k} {v}" for k, v in statuses.items())
    )
    succ = success_table(df).map(lambda v: "-" if v != v else f"{100 * v:.0f}%")
    extra = [
        f"Median {key} of solved runs by number of agents\n"
        + stats_table(df, key).to_string(float_format=_number)
        for key in stats
    ]
    return "\n\n".join(
        [
            head,
            "Success rate by number of agents\n" + succ.to_string(),
            "Runtime of solved runs (s); PAR2 counts an unsolved run as 2 x its time limit\n"
            + runtime_table(df).to_string(float_format=lambda v: f"{v:.3g}"),
            "Cost over lower bound (solved runs with a plan)\n"
            + cost_table(df).to_string(float_format=lambda v: f"{v:.4f}"),
            *extra,
        ]
    )


# ---------------------------------------------------------------- figures
def _time_limit(df: pd.DataFrame) -> float:
    """The largest time limit of the runs (NaN without runs)."""
    largest: Any = df["time_limit"].max() if len(df) else math.nan
    return float(largest)


def _figure() -> tuple[Figure, Axes]:
    """A new figure of the reports' size and its one Axes."""
    from matplotlib.figure import Figure  # heavy module: matplotlib

    fig = Figure(figsize=(6.5, 4.0), layout="constrained")
    return fig, fig.add_subplot()


def _finish(fig: Figure, ax: Axes, title: str | None) -> Figure:
    """Grid, legend and the optional title of a report figure."""
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    if title:
        ax.set_title(title)
    return fig


def success_rate_figure(df: pd.DataFrame, *, title: str | None = None) -> Figure:
    """Success rate against the number of agents, one curve per solver.

    Example
    -------
    >>> import pandas as pd
    >>> df = pd.DataFrame({"label": ["a", "a", "b", "b"], "agents": [2, 4, 2, 4],
    ...                    "solved": [True, True, True, False]})
    >>> fig = success_rate_figure(df)
    >>> [ln.get_label() for ln in fig.axes[0].get_lines()]
    ['a', 'b']
    """
    fig, ax = _figure()
    table = success_table(df)
    for i, (label, row) in enumerate(table.iterrows()):
        row = row.dropna()
        y = 100 * row.to_numpy(dtype=float)
        ax.plot(row.index.astype(float), y, marker=MARKERS[i % len(MARKERS)], label=str(label))
    ax.set_xlabel("agents")
    ax.set_ylabel("solved runs (%)")
    ax.set_ylim(-5, 105)
    return _finish(fig, ax, title)


def runtime_figure(df: pd.DataFrame, *, title: str | None = None) -> Figure:
    """Median runtime of the solved runs against the number of agents, one line per
    solver (log scale), with the largest time limit dashed.

    Example
    -------
    >>> import pandas as pd
    >>> df = pd.DataFrame({"label": ["a", "a", "a"], "agents": [2, 2, 4],
    ...                    "runtime": [1.0, 3.0, 5.0], "solved": [True, True, False],
    ...                    "time_limit": [10.0] * 3})
    >>> ax = runtime_figure(df).axes[0]
    >>> ax.get_lines()[0].get_ydata().tolist()
    [2.0]
    """
    fig, ax = _figure()
    for i, label in enumerate(_labels(df)):
        d: Any = df[(df["label"] == label) & df["solved"]]
        med = d.groupby("agents")["runtime"].median()
        x, y = med.index.astype(float), med.to_numpy(dtype=float)
        ax.plot(x, y, marker=MARKERS[i % len(MARKERS)], label=label)
    limit = _time_limit(df)
    if math.isfinite(limit):
        ax.axhline(limit, color="grey", ls="--", lw=1, label="time limit")
    ax.set_yscale("log")
    ax.set_xlabel("agents")
    ax.set_ylabel("median runtime of solved runs (s)")
    return _finish(fig, ax, title)


def cactus_figure(df: pd.DataFrame, *, title: str | None = None, logx: bool = True) -> Figure:
    """Cactus plot: for each solver, how many runs it solves within a given time.

    Example
    -------
    >>> import pandas as pd
    >>> df = pd.DataFrame({"label": ["a", "a", "b"], "runtime": [0.1, 2.0, 0.5],
    ...                    "solved": [True, True, False], "time_limit": [10.0] * 3})
    >>> fig = cactus_figure(df)
    >>> [ln.get_label() for ln in fig.axes[0].get_lines()][:2]
    ['a', 'b']
    """
    fig, ax = _figure()
    for label in _labels(df):
        t = sorted(df.loc[(df["label"] == label) & df["solved"], "runtime"].astype(float))
        ax.step(t, range(1, len(t) + 1), where="post", label=label, marker=".")
    limit = _time_limit(df)
    if math.isfinite(limit):
        ax.axvline(limit, color="grey", ls="--", lw=1, label="time limit")
    from matplotlib.ticker import MaxNLocator  # heavy module: matplotlib

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("runtime (s)")
    ax.set_ylabel("runs solved within that time")
    if logx:
        ax.set_xscale("log")
    return _finish(fig, ax, title)


def save_figures(db: str | Path, folder: str | Path) -> list[Path]:
    """Write ``success_rate.png``, ``runtime.png`` and ``cactus.png`` of a sweep
    database to ``folder``."""
    df = read_runs(db)
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in (
        ("success_rate.png", success_rate_figure(df)),
        ("runtime.png", runtime_figure(df)),
        ("cactus.png", cactus_figure(df)),
    ):
        p = out / name
        fig.savefig(p, dpi=100)
        paths.append(p)
    return paths


# ---------------------------------------------------------------- export
def export(db: str | Path, out: str | Path) -> int:
    """Write table ``runs`` to ``out`` (``.csv`` or ``.parquet``); returns the row count.

    CSV needs nothing beyond the standard library; Parquet needs pyarrow (the
    ``parquet`` extra). The file is written to a temporary name and renamed, so a
    failed export leaves no half-written file.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.experiments import store
    >>> d = tempfile.mkdtemp()
    >>> store.connect(os.path.join(d, "r.sqlite")).close()
    >>> export(os.path.join(d, "r.sqlite"), os.path.join(d, "r.csv"))
    0
    """
    target = Path(out)
    suffix = target.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise InputError(f"{target}: export writes .csv or .parquet files")
    if suffix == ".parquet" and importlib.util.find_spec("pyarrow") is None:
        raise InputError(
            "Parquet export needs pyarrow: pip install 'hierplan_opt[parquet]' (or export .csv)"
        )
    con = store.open_existing(db)
    try:
        cur = con.execute("SELECT * FROM runs ORDER BY id")
        names = [d[0] for d in cur.description]
        data: list[tuple[Any, ...]] = cur.fetchall()
    finally:
        con.close()
    tmp = target.with_name(target.name + ".part")
    try:
        if suffix == ".csv":
            with open(tmp, "w", newline="", encoding="utf-8") as f:
                w = csv.writer(f)
                w.writerow(names)
                w.writerows(data)
        else:
            import pandas as pd  # heavy module: pandas

            pd.DataFrame.from_records(data, columns=names).to_parquet(tmp, index=False)
        tmp.replace(target)
    finally:
        tmp.unlink(missing_ok=True)
    return len(data)
