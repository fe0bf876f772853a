"""Where the shipped benchmark instances and the canned sweep specs are.

The repository's ``instances/`` folder (MovingAI samples, the overview paper's examples)
is package data: ``hierplan_opt/data`` points at it in a checkout and holds a copy of it
in an installed wheel, so benchmarks and canned sweeps run from an installed package.
The environment variable ``HIERPLAN_INSTANCES`` (or ``hierplan sweep --instances-dir``)
names another folder with the same layout (``movingai/``, ``paper/``).

Canned specs are YAML files in ``hierplan_opt/experiments/specs/``: the tables of
``hierplan bench AREA`` as sweeps (``hierplan sweep --canned NAME``).
"""

from __future__ import annotations

import os
from pathlib import Path

from hierplan_opt.core.errors import InputError

ENV = "HIERPLAN_INSTANCES"
SPECS = Path(__file__).resolve().parent / "specs"


def instances_dir() -> Path:
    """The folder of benchmark instances: ``$HIERPLAN_INSTANCES`` or the package's own.

    Example
    -------
    >>> (instances_dir() / "movingai" / "empty-8-8.map").is_file()
    True
    """
    env = os.environ.get(ENV)
    if env:
        p = Path(env)
        if not p.is_dir():
            raise InputError(f"{ENV}={env}: no such folder")
        return p
    return Path(__file__).resolve().parents[1] / "data"


def shipped_file(name: str | Path) -> Path:
    """A benchmark file named by its path in the repository (``instances/...``), in
    :func:`instances_dir` (the package's copy in an installed wheel).

    Example
    -------
    >>> shipped_file("instances/paper/formation-usc.yaml").is_file()
    True
    """
    parts = Path(name).parts
    return instances_dir().joinpath(*(parts[1:] if parts[:1] == ("instances",) else parts))


def movingai_files(scen_stem: str) -> tuple[Path, Path]:
    """(map, scen) of a shipped MovingAI scenario, e.g. ``"room-32-32-4-even-1"``.

    Example
    -------
    >>> m, s = movingai_files("empty-8-8-even-1")
    >>> m.name, s.name
    ('empty-8-8.map', 'empty-8-8-even-1.scen')
    """
    folder = instances_dir() / "movingai"
    map_name = scen_stem.rsplit("-", 2)[0] + ".map"
    mp, scen = folder / map_name, folder / f"{scen_stem}.scen"
    for p in (mp, scen):
        if not p.is_file():
            raise InputError(f"benchmark file {p.name} not found in {folder} (set ${ENV})")
    return mp, scen


def canned_specs() -> dict[str, str]:
    """Name -> one-line description (the spec's first comment line) of each canned spec."""
    out = {}
    for p in sorted(SPECS.glob("*.yaml")):
        first = p.read_text(encoding="utf-8").splitlines()[0] if p.stat().st_size else ""
        out[p.stem] = first.lstrip("# ").strip()
    return out


def canned_spec(name: str) -> Path:
    """The spec file of canned sweep ``name``.

    Example
    -------
    >>> canned_spec("cbs-quick").name
    'cbs-quick.yaml'
    """
    p = SPECS / f"{name}.yaml"
    if not p.is_file():
        raise InputError(f"unknown canned sweep {name!r} (known: {', '.join(canned_specs())})")
    return p
