"""``hierplan view``: one self-contained HTML file that plays a :class:`~.scene.Scene`.

The page needs no server and no network: the viewer (``viewer.html``, canvas 2D) and
the data are in the file. Numbers travel as little-endian typed arrays, deflated and
base64-encoded in one block (the browser inflates them with ``DecompressionStream``);
a discrete plan is stored as per-robot vertex changes between timesteps, which deflate
to a few bits per robot and step. Descriptive fields travel as JSON.

The page exposes ``window.hierplan`` for tests and scripts: ``ready`` (a promise),
``seek(t)``, ``play()``, ``pause()``, ``setSpeed(s)``, ``time()``, ``drawn()`` (the
positions used by the last frame), ``screenOf(k)`` (a robot's centre in CSS pixels)
and ``measure(ms)`` (frames per second while playing).
"""

from __future__ import annotations

import base64
import json
import math
import zlib
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from hierplan_opt.io.files import check_output, write_text
from hierplan_opt.viz.scene import LAYER_COLORS, Scene, closest_pairs

#: Colours of robots without teams (one per index modulo its length) and of teams.
PALETTE = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
    "#17becf", "#bcbd22", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173",
    "#3182bd", "#e6550d", "#31a354", "#756bb1", "#636363", "#6baed6", "#fd8d3c",
    "#74c476", "#9e9ac8", "#a55194",
]  # fmt: skip


class _Blob:
    """Typed arrays packed into one buffer (each 8-byte aligned) with their layout."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.layout: dict[str, list[Any]] = {}
        self.size = 0

    def add(self, name: str, arr: np.ndarray) -> None:
        kinds = {
            np.dtype(np.float32): "f32",
            np.dtype(np.uint8): "u8",
            np.dtype(np.uint16): "u16",
            np.dtype(np.int32): "i32",
            np.dtype(np.uint32): "u32",
        }
        a = np.ascontiguousarray(arr)
        kind = kinds[a.dtype]
        data = a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
        self.layout[name] = [self.size, int(a.size), kind]
        pad = (-len(data)) % 8
        self.parts.append(data + b"\0" * pad)
        self.size += len(data) + pad

    def encoded(self) -> str:
        return base64.b64encode(zlib.compress(b"".join(self.parts), 6)).decode("ascii")


def _colours(scene: Scene) -> tuple[np.ndarray, list[str], list[str]]:
    """Colour index per robot, the colours, and the legend's labels for them."""
    K = scene.num_agents
    if scene.team_names:
        pal = [PALETTE[t % len(PALETTE)] for t in range(len(scene.team_names))]
        return scene.team.astype(np.uint16), pal, list(scene.team_names)
    if len(PALETTE) >= K:
        return np.arange(K, dtype=np.uint16), PALETTE[:K], list(scene.names)
    return (np.arange(K) % len(PALETTE)).astype(np.uint16), list(PALETTE), []


def scene_payload(scene: Scene, *, clearance_samples: int = 300) -> tuple[dict[str, Any], str]:
    """The JSON header and the encoded binary block of the page for ``scene``."""
    g = scene.graph
    blob = _Blob()
    head: dict[str, Any] = {
        "title": scene.title,
        "source": scene.source,
        "K": scene.num_agents,
        "dim": scene.dim,
        "scale": scene.scale,
        "end": scene.end,
        "names": scene.names,
        "stats": {k: v for k, v in scene.stats.items() if _plain(v)},
        "layers": LAYER_COLORS,
        "guaranteed": scene.guaranteed,
        "margin": scene.margin,
    }
    if g.kind == "grid" and g.shape is not None:
        W, H = int(g.shape[0]), int(g.shape[1])
        blocked = ~g.passable
        if len(g.shape) == 3:
            D = int(g.shape[2])
            shade = blocked.reshape(D, H, W).mean(axis=0)
            head["map"] = {"kind": "grid", "w": W, "h": H, "depth": D}
        else:
            shade = blocked.reshape(H, W).astype(float)
            head["map"] = {"kind": "grid", "w": W, "h": H, "depth": 1}
        blob.add("cells", np.round(shade * 255).astype(np.uint8))
    else:
        xy = g.coords[:, :2]
        edges = np.array(
            [(u, int(v)) for u in range(g.n) for v in g.adj[u] if g.directed or u < v],
            dtype=np.uint32,
        ).reshape(-1, 2)
        head["map"] = {"kind": "roadmap", "n": int(g.n), "directed": bool(g.directed)}
        blob.add("vxy", xy.astype(np.float32))
        blob.add("edges", edges)
    col, pal, labels = _colours(scene)
    head["palette"] = pal
    head["paletteLabels"] = labels
    blob.add("color", col)
    # robots are drawn to scale; robots without a footprint (radius 0) as 0.3 of the
    # distance between neighbouring vertices, and the legend says so
    spacing = 1.0 if g.kind == "grid" or not len(g.lengths) else float(np.median(g.lengths))
    pointlike = scene.radius <= 0
    head["pointRadius"] = 0.3 * spacing if pointlike.any() else None
    drawn = np.where(pointlike, 0.3 * spacing, scene.radius)
    blob.add("radius", drawn.astype(np.float32))
    # goal markers: each robot's goal in its colour, or (teams) every target in the
    # team's colour
    has = np.isfinite(scene.goals).all(axis=1)
    marks, markc = scene.goals[has], col[has]
    if scene.targets is not None and len(scene.targets):
        marks = np.concatenate([marks, scene.targets])
        tc = (
            scene.target_team
            if scene.team_names and scene.target_team is not None
            else np.zeros(len(scene.targets), int)
        )
        markc = np.concatenate([markc, tc.astype(np.uint16)])
    blob.add("marks", marks.reshape(-1, scene.dim).astype(np.float32))
    blob.add("markc", markc.astype(np.uint16))
    head["hasGoals"] = bool(len(marks))
    head["goalWord"] = "target" if scene.targets is not None else "goal"
    if scene.steps is not None:
        head["motion"] = {"mode": "steps", "dt": scene.dt, "T": int(len(scene.steps))}
        blob.add("vcoords", g.coords.astype(np.float32))
        st = scene.steps.astype(np.int64)
        delta = np.empty_like(st)
        delta[0] = st[0]
        delta[1:] = st[1:] - st[:-1]
        blob.add("steps", delta.astype(np.int32))
    else:
        assert scene.keys is not None
        lens = np.array([len(k) for k in scene.keys], dtype=np.int64)
        off = np.concatenate([[0], np.cumsum(lens)]).astype(np.uint32)
        allk = np.concatenate(scene.keys) if len(scene.keys) else np.zeros((0, 1 + scene.dim))
        head["motion"] = {"mode": "keys", "slack": False}
        blob.add("koff", off)
        # times relative to each robot's first key in float32 would lose little; keep
        # absolute times (float32 has 7 digits: 0.1 ms at 1000 s)
        blob.add("kt", allk[:, 0].astype(np.float32))
        for d, axis in enumerate("xyz"[: scene.dim]):
            blob.add("k" + axis, allk[:, 1 + d].astype(np.float32))
        if scene.slack is not None:
            blob.add("ks", np.concatenate(scene.slack).astype(np.float32))
            head["motion"]["slack"] = True
    ev = sorted(scene.events, key=lambda e: e["time"])
    index = {n: k for k, n in enumerate(scene.names)}
    head["events"] = {
        "t": [round(float(e["time"]), 6) for e in ev],
        "a": [index.get(e["agent"], -1) for e in ev],
        "kind": [e["kind"] for e in ev],
        "layer": [e["layer"] for e in ev],
        "delay": [round(float(e["delay"]), 6) if math.isfinite(e["delay"]) else None for e in ev],
        "detail": [e["detail"][:120] for e in ev],
    }
    n = clearance_samples if scene.num_agents <= 2000 else min(clearance_samples, 120)
    head["closest"] = closest_pairs(scene, n)
    data = blob.encoded()
    head["blobs"] = blob.layout
    return head, data


def _plain(v: Any) -> bool:
    return isinstance(v, (str, bool, int)) or (isinstance(v, float) and math.isfinite(v))


def render_html(scene: Scene) -> str:
    """The whole page for ``scene`` (a string)."""
    head, data = scene_payload(scene)
    template = resources.files("hierplan_opt.viz").joinpath("viewer.html").read_text("utf-8")
    text = json.dumps(head, separators=(",", ":"), allow_nan=False)
    text = text.replace("</", "<\\/")  # never close the script element early
    title = scene.title.replace("&", "&amp;").replace("<", "&lt;")
    return template.replace("__TITLE__", title).replace("__HEAD__", text).replace("__DATA__", data)


def write_view(scene: Scene, path: str | Path) -> Path:
    """Write the viewer page of ``scene`` to ``path`` (``.html``), atomically.

    Example
    -------
    >>> import os, tempfile
    >>> from hierplan_opt.core.graph import Graph
    >>> from hierplan_opt.core.instance import Instance
    >>> from hierplan_opt.core.plan import Plan
    >>> from hierplan_opt.viz.scene import scene_from_plan
    >>> inst = Instance.mapf(Graph.grid(3, 1), [(0, 0)], [(2, 0)])
    >>> f = os.path.join(tempfile.mkdtemp(), "v.html")
    >>> _ = write_view(scene_from_plan(inst, Plan.from_paths([[0, 1, 2]])), f)
    >>> open(f).read().startswith("<!DOCTYPE html>")
    True
    """
    check_output(path, what="viewer page", suffixes=(".html", ".htm"))
    return write_text(path, render_html(scene))


__all__ = ["PALETTE", "render_html", "scene_payload", "write_view"]
