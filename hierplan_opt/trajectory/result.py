"""Refined trajectories: piecewise-quadratic motion per robot, sampling, CSV and NPZ files.

Every robot's motion is exact on its grid: on interval ``k`` (``t_k <= t < t_{k+1}``)
the position is ``p_k + v_k tau + a_k tau^2 / 2`` and the heading
``theta_k + omega_k tau + alpha_k tau^2 / 2`` with ``tau = t - t_k``; after its last
node a robot rests at its goal.

Files: CSV with the header ``agent,t,x,y,vx,vy`` (2D) or ``agent,t,x,y,z,vx,vy,vz``
(3D), plus ``theta`` when any robot drives differentially, one row per agent and
sample, preceded by ``# key: value`` comment lines; NPZ with arrays ``t (S,)``,
``pos (K, S, dim)``, ``vel``, ``acc``, ``theta (K, S)``, ``agents (K,)`` and the
statistics as a JSON string ``meta``; NPZ files also hold the exact motion (``exact``,
a JSON string, and ``exact_*`` arrays), which :func:`read_trajectories` loads back
(``hierplan simulate --trajectories``).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.core.errors import InputError
from hierplan_opt.core.reprs import short_repr
from hierplan_opt.io.values import plain, to_json

#: Default sampling step of the output files (seconds).
DEFAULT_DT = 0.1


@dataclass(frozen=True, eq=False)
class RobotTrajectory:
    """One robot's refined motion (read-only arrays).

    Attributes
    ----------
    name, model : str
        ``model`` is ``"double_integrator"`` or ``"unicycle"``.
    t : (n+1,) float
        Grid nodes (seconds), non-decreasing; ``t[-1]`` is the arrival at the goal.
    p, v : (n+1, dim) float
        Position (metres) and velocity at the nodes.
    a : (n, dim) float
        Constant acceleration on each interval.
    theta, omega : (n+1,) float
        Heading (radians, x-y plane) and turn rate at the nodes.
    alpha : (n,) float
        Constant turn acceleration on each interval.
    event_times : (m,) float
        Time at which the robot passes each of its STN events (way-points).
    limits : dict
        ``v_max``, ``a_max``, ``omega_max``, ``alpha_max`` the trajectory was built for
        (``inf`` when unlimited).
    stats : dict
        ``solver``, ``status``, ``iterations``, ``solve_time``, ``intervals``.
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    name: str
    model: str
    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    event_times: np.ndarray
    limits: dict[str, float]
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def arrival(self) -> float:
        return float(self.t[-1])

    @property
    def dim(self) -> int:
        return int(self.p.shape[1])

    def _locate(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = len(self.t) - 1
        if n == 0:
            z = np.zeros(len(ts), dtype=np.int64)
            return z, np.zeros(len(ts)), np.ones(len(ts), dtype=bool)
        k = np.clip(np.searchsorted(self.t, ts, side="right") - 1, 0, n - 1)
        after = ts >= self.t[-1]
        tau = np.clip(ts - self.t[k], 0.0, None)
        return k, tau, after

    def state(self, ts: np.ndarray) -> dict[str, np.ndarray]:
        """Position, velocity, acceleration, heading, turn rate at the times ``ts``."""
        ts = np.asarray(ts, dtype=float)
        k, tau, after = self._locate(ts)
        if len(self.t) == 1:
            S = len(ts)
            return {
                "p": np.repeat(self.p[:1], S, axis=0),
                "v": np.zeros((S, self.dim)),
                "a": np.zeros((S, self.dim)),
                "theta": np.full(S, float(self.theta[0])),
                "omega": np.zeros(S),
            }
        tc = tau[:, None]
        a = self.a[k]
        p = self.p[k] + self.v[k] * tc + 0.5 * a * tc * tc
        v = self.v[k] + a * tc
        th = self.theta[k] + self.omega[k] * tau + 0.5 * self.alpha[k] * tau * tau
        om = self.omega[k] + self.alpha[k] * tau
        p[after] = self.p[-1]
        v[after] = 0.0
        a = np.where(after[:, None], 0.0, a)
        th[after] = self.theta[-1]
        om[after] = 0.0
        before = ts < self.t[0]
        p[before] = self.p[0]
        v[before] = 0.0
        a[before] = 0.0
        return {"p": p, "v": v, "a": a, "theta": th, "omega": om}


@dataclass(frozen=True, eq=False)
class Trajectories:
    """The result of :func:`hierplan_opt.trajectory.refine`.

    Attributes
    ----------
    robots : tuple of :class:`RobotTrajectory`
    mode : str
        ``"path"`` or ``"corridor"``.
    corridor : float
        Half-width ``c`` of the corridor (0 in path mode).
    safety_distance : float
        The smallest distance between robot centres the refinement guarantees over all
        pairs: :meth:`required` is the distance of one pair.
    schedule_safety_distance : float
        The schedule's (``min r_i + r_j + margin``).
    stretch : float
        Factor by which the schedule's times were scaled (1: not stretched).
    guarantee : str
        One sentence saying where ``safety_distance`` comes from.
    windows : Windows
        The decoupled windows (after stretching) the robots were refined in.
    stats : dict
    radius : tuple of float
        The robots' radii (metres; empty: unknown, only ``safety_distance`` is known).
    margin : float
        Extra clearance of the schedule beyond the radii.
    enforced : bool
        Whether the schedule guaranteed clearance (False for ``clearance=False``).
    """

    __repr__ = short_repr  # arrays and long tuples summarised (core/reprs)

    robots: tuple[RobotTrajectory, ...]
    mode: str
    corridor: float
    safety_distance: float
    schedule_safety_distance: float
    stretch: float
    guarantee: str
    windows: Any = field(repr=False, default=None)
    stats: dict[str, Any] = field(default_factory=dict)
    radius: tuple[float, ...] = ()
    margin: float = 0.0
    enforced: bool = True

    def required(self, i: int, j: int) -> float:
        """The distance robots ``i`` and ``j`` keep: ``r_i + r_j + margin`` (path mode),
        minus ``2 c`` in corridor mode, 0 without a guarantee.

        Example
        -------
        >>> T = Trajectories((), "corridor", 0.05, 0.5, 0.6, 1.0, "", radius=(0.3, 0.3))
        >>> round(T.required(0, 1), 9)
        0.5
        """
        if not self.enforced:
            return 0.0
        if not self.radius:
            return self.safety_distance
        d = self.radius[i] + self.radius[j] + self.margin
        return max(d - 2.0 * self.corridor, 0.0) if d > 0 else 0.0

    @property
    def agent_names(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.robots)

    @property
    def num_agents(self) -> int:
        return len(self.robots)

    @property
    def dim(self) -> int:
        return self.robots[0].dim if self.robots else 2

    @property
    def makespan(self) -> float:
        return max((r.arrival for r in self.robots), default=0.0)

    @property
    def has_heading(self) -> bool:
        return any(r.model == "unicycle" for r in self.robots)

    def sample(self, dt: float = DEFAULT_DT, horizon: float | None = None) -> dict[str, np.ndarray]:
        """Every robot at the times ``0, dt, ..., horizon`` (default: the makespan).

        Returns ``t (S,)``, ``pos``, ``vel``, ``acc`` of shape ``(K, S, dim)`` and
        ``theta``, ``omega`` of shape ``(K, S)``.
        """
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise InputError(f"the sampling step must be a positive number, got {dt!r}")
        H = self.makespan if horizon is None else float(horizon)
        S = int(math.floor(H / dt + 1e-9)) + 1
        ts = np.arange(S) * dt
        if ts[-1] < H - 1e-12:
            ts = np.append(ts, H)
        K, D = self.num_agents, self.dim
        out = {
            "t": ts,
            "pos": np.empty((K, len(ts), D)),
            "vel": np.empty((K, len(ts), D)),
            "acc": np.empty((K, len(ts), D)),
            "theta": np.empty((K, len(ts))),
            "omega": np.empty((K, len(ts))),
        }
        for j, r in enumerate(self.robots):
            s = r.state(ts)
            out["pos"][j], out["vel"][j], out["acc"][j] = s["p"], s["v"], s["a"]
            out["theta"][j], out["omega"][j] = s["theta"], s["omega"]
        return out

    def statistics(self) -> dict[str, Any]:
        """Plain values for file headers and the CLI."""
        return {
            "mode": self.mode,
            "corridor": self.corridor,
            "safety_distance": self.safety_distance,
            "schedule_safety_distance": self.schedule_safety_distance,
            "margin": self.margin,
            "clearance_guaranteed": self.enforced,
            "stretch": self.stretch,
            "makespan": self.makespan,
            "guarantee": self.guarantee,
            **{k: v for k, v in self.stats.items() if isinstance(v, (int, float, str))},
        }


# ---------------------------------------------------------------------- files
FORMATS = (".csv", ".npz")


def check_output_path(path: str | Path) -> Path:
    """Refuse an output path whose extension is not ``.csv``/``.npz`` (before any work)."""
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise InputError(f"{path}: the trajectory file must end in .csv or .npz")
    if path.is_dir():
        raise InputError(f"{path}: is a directory")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{path}: directory {parent} does not exist")
    return path


def trajectories_csv(traj: Trajectories, dt: float = DEFAULT_DT) -> str:
    """The CSV text: ``# key: value`` lines, then ``agent,t,x,y[,z],vx,vy[,vz][,theta]``.

    Example
    -------
    >>> r = RobotTrajectory("a", "double_integrator", np.array([0.0, 1.0]),
    ...     np.array([[0.0, 0.0], [0.5, 0.0]]), np.array([[0.0, 0.0], [1.0, 0.0]]),
    ...     np.array([[1.0, 0.0]]), np.zeros(2), np.zeros(2), np.zeros(1), np.zeros(2), {})
    >>> T = Trajectories((r,), "path", 0.0, 0.25, 0.25, 1.0, "")
    >>> print(trajectories_csv(T, dt=0.5).split("\\n", 9)[-1].strip())
    agent,t,x,y,vx,vy
    a,0,0,0,0,0
    a,0.5,0.125,0,0.5,0
    a,1,0.5,0,0,0
    """
    s = traj.sample(dt)
    buf = io.StringIO()
    for k, v in traj.statistics().items():
        buf.write(f"# {k}: {to_json(v)}\n")
    axes = ["x", "y", "z"][: traj.dim]
    head = ["agent", "t", *axes, *("v" + a for a in axes)]
    heading = traj.has_heading
    if heading:
        head.append("theta")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    ts = s["t"]
    for j, name in enumerate(traj.agent_names):
        P, V, TH = s["pos"][j], s["vel"][j], s["theta"][j]
        for i in range(len(ts)):
            row = [name, _f(ts[i]), *(_f(x) for x in P[i]), *(_f(x) for x in V[i])]
            if heading:
                row.append(_f(TH[i]))
            w.writerow(row)
    return buf.getvalue()


def write_trajectories(traj: Trajectories, path: str | Path, dt: float = DEFAULT_DT) -> Path:
    """Write CSV or NPZ (by extension) atomically: no half-written file on failure."""
    path = check_output_path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", suffix=path.suffix)
    os.close(fd)
    try:
        if path.suffix.lower() == ".csv":
            Path(tmp).write_text(trajectories_csv(traj, dt))
        else:
            s = traj.sample(dt)
            np.savez_compressed(
                tmp,
                t=s["t"],
                pos=s["pos"],
                vel=s["vel"],
                acc=s["acc"],
                theta=s["theta"],
                agents=np.array(traj.agent_names),
                meta=np.array(to_json(traj.statistics())),
                **_exact_arrays(traj),
            )
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


_EXACT = ("t", "p", "v", "a", "theta", "omega", "alpha", "event_times")


def _exact_arrays(traj: Trajectories) -> dict[str, Any]:
    """The robots' exact motion, concatenated (``exact_<field>``) with lengths in ``exact``."""
    head = {
        "mode": traj.mode,
        "corridor": traj.corridor,
        "safety_distance": traj.safety_distance,
        "schedule_safety_distance": traj.schedule_safety_distance,
        "stretch": traj.stretch,
        "guarantee": traj.guarantee,
        "radius": list(traj.radius),
        "margin": traj.margin,
        "enforced": traj.enforced,
        "robots": [
            {
                "name": r.name,
                "model": r.model,
                "limits": {k: plain(v) for k, v in r.limits.items()},
                **{f: len(getattr(r, f)) for f in _EXACT},
            }
            for r in traj.robots
        ],
    }
    out: dict[str, Any] = {"exact": np.array(json.dumps(head))}
    for f in _EXACT:
        parts = [np.asarray(getattr(r, f), dtype=float) for r in traj.robots]
        out["exact_" + f] = np.concatenate(parts) if parts else np.zeros(0)
    return out


def read_trajectories(path: str | Path) -> Trajectories:
    """Load the :class:`Trajectories` of an NPZ file written by :func:`write_trajectories`.

    Raises :class:`InputError` (one line) for anything else.
    """
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise InputError(f"{path}: refined trajectories are read from the .npz of hierplan refine")
    try:
        with np.load(path, allow_pickle=False) as z:
            if "exact" not in z:
                raise InputError(
                    f"{path}: no exact motion in this file (write it with hierplan refine --out "
                    "FILE.npz)"
                )
            head = json.loads(str(z["exact"]))
            arrays = {f: np.asarray(z["exact_" + f], dtype=float) for f in _EXACT}
    except InputError:
        raise
    except (OSError, ValueError, KeyError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a trajectories file ({exc})") from None
    robots = []
    at = dict.fromkeys(_EXACT, 0)
    try:
        for rob in head["robots"]:
            parts: dict[str, np.ndarray] = {}
            for f in _EXACT:
                n = int(rob[f])
                parts[f] = arrays[f][at[f] : at[f] + n]
                at[f] += n
                if len(parts[f]) != n:
                    raise ValueError(f"{f} is short")
            for v in parts.values():
                v.setflags(write=False)
            robots.append(
                RobotTrajectory(
                    name=str(rob["name"]),
                    model=str(rob["model"]),
                    t=parts["t"],
                    p=parts["p"],
                    v=parts["v"],
                    a=parts["a"],
                    theta=parts["theta"],
                    omega=parts["omega"],
                    alpha=parts["alpha"],
                    event_times=parts["event_times"],
                    limits={
                        # null: no limit (files hold no inf; older files wrote "inf")
                        k: math.inf if v is None else float(v)
                        for k, v in rob["limits"].items()
                    },
                )
            )
        return Trajectories(
            tuple(robots),
            str(head["mode"]),
            float(head["corridor"]),
            float(head["safety_distance"]),
            float(head["schedule_safety_distance"]),
            float(head["stretch"]),
            str(head["guarantee"]),
            radius=tuple(float(r) for r in head["radius"]),
            margin=float(head["margin"]),
            enforced=bool(head["enforced"]),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: damaged trajectories file ({exc})") from None


def _f(x: float) -> str:
    r = round(float(x), 9)
    if r == 0:
        return "0"
    return repr(int(r)) if r == int(r) and abs(r) < 1e15 else repr(r)
