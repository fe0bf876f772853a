"""The SQLite file of a sweep: table ``runs`` (one row per finished run) and ``sweeps``.

Only the process that drives a sweep writes (local threads and Dask workers hand their
rows back to it), one committed ``INSERT`` per finished run, so a sweep killed at any
moment loses only the runs that were still going. Every run has a ``key``, a hash of
what determines its outcome (solver, options, objective, instance content, K, seed,
limits); a key already in ``runs`` is never run again, which is how ``--resume`` and a
repeated spec re-use finished runs.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from hierplan_opt.core.errors import InputError
from hierplan_opt.io.files import read_head
from hierplan_opt.io.values import to_json

#: Columns of ``runs`` in order, with their SQLite types.
COLUMNS: tuple[tuple[str, str], ...] = (
    ("id", "INTEGER PRIMARY KEY"),
    ("key", "TEXT NOT NULL UNIQUE"),
    ("sweep", "TEXT"),
    ("solver", "TEXT NOT NULL"),
    ("label", "TEXT NOT NULL"),
    ("options", "TEXT"),  # JSON
    ("objective", "TEXT"),
    ("instance", "TEXT NOT NULL"),
    ("instance_hash", "TEXT"),
    ("agents", "INTEGER"),
    ("seed", "INTEGER"),
    ("time_limit", "REAL"),
    ("memory_limit_mb", "REAL"),
    ("status", "TEXT NOT NULL"),
    ("cost", "REAL"),
    ("lower_bound", "REAL"),
    ("runtime", "REAL"),  # the solver's own time (hierplan_opt.solve)
    ("wall", "REAL"),  # the whole process: start, imports, instance, solve
    ("peak_mb", "REAL"),  # peak resident memory of the run's process
    ("expanded", "INTEGER"),  # high-level nodes expanded (search solvers)
    ("generated", "INTEGER"),  # high-level nodes generated
    ("low_level_expanded", "INTEGER"),
    ("stats", "TEXT"),  # JSON: every statistic the solver reported
    ("error", "TEXT"),
    ("versions", "TEXT"),  # JSON: python and package versions of the run
    ("host", "TEXT"),
    ("finished_at", "TEXT"),
)
NAMES = tuple(c for c, _ in COLUMNS)
JSON_COLUMNS = ("options", "stats", "versions")
_SQLITE_MAGIC = b"SQLite format 3\x00"


def is_database(path: str | Path) -> bool:
    """True when ``path`` is an SQLite file (a regular file: a FIFO is never waited on)."""
    try:
        return read_head(path, 16) == _SQLITE_MAGIC
    except InputError:
        return False


def connect(path: str | Path) -> sqlite3.Connection:
    """Open (creating if needed) a sweep database with its tables.

    Example
    -------
    >>> import tempfile, os
    >>> con = connect(os.path.join(tempfile.mkdtemp(), "r.sqlite"))
    >>> finished_keys(con)
    set()
    """
    p = Path(path)
    # an existing FIFO or device is refused at once (read_head), never opened by SQLite
    if p.exists() and read_head(p, 16) not in (b"", _SQLITE_MAGIC):
        raise InputError(f"{p}: not an SQLite database")
    p.parent.mkdir(parents=True, exist_ok=True)
    con = sqlite3.connect(p, timeout=30.0)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute(f"CREATE TABLE IF NOT EXISTS runs ({', '.join(f'{c} {t}' for c, t in COLUMNS)})")
    con.execute(
        "CREATE TABLE IF NOT EXISTS sweeps (id INTEGER PRIMARY KEY, name TEXT, spec TEXT, "
        "folder TEXT, started_at TEXT, finished_at TEXT, runs INTEGER)"
    )
    con.commit()
    return con


def open_existing(path: str | Path) -> sqlite3.Connection:
    """Open a sweep database that must exist and hold a ``runs`` table."""
    p = Path(path)
    if read_head(p, 16) != _SQLITE_MAGIC:  # refuses a missing file, a FIFO, a device
        raise InputError(f"{p}: not an SQLite database")
    con = sqlite3.connect(p, timeout=30.0)
    if con.execute("SELECT name FROM sqlite_master WHERE name='runs'").fetchone() is None:
        con.close()
        raise InputError(f"{p}: not a sweep database (no table 'runs')")
    return con


def finished_keys(con: sqlite3.Connection) -> set[str]:
    """Keys of the runs already recorded (not the SKIPPED ones: ``stop_on_failure`` left
    them unrun, so a later sweep runs them)."""
    return {k for (k,) in con.execute("SELECT key FROM runs WHERE status != 'SKIPPED'")}


def insert_run(con: sqlite3.Connection, row: Mapping[str, Any]) -> bool:
    """Record one finished run (committed at once); False if its key is already there."""
    values = []
    for name in NAMES[1:]:
        v = row.get(name)
        if name in JSON_COLUMNS and v is not None and not isinstance(v, str):
            v = to_json(v, sort_keys=True, default=str)
        values.append(v)
    # a run that a stop_on_failure had skipped takes its row
    con.execute("DELETE FROM runs WHERE key = ? AND status = 'SKIPPED'", (row.get("key"),))
    cur = con.execute(
        f"INSERT OR IGNORE INTO runs ({', '.join(NAMES[1:])}) "
        f"VALUES ({', '.join('?' * (len(NAMES) - 1))})",
        values,
    )
    con.commit()
    return cur.rowcount == 1


def start_sweep(con: sqlite3.Connection, name: str, spec: str, folder: str, runs: int) -> int:
    """Record that a sweep starts; returns its id."""
    cur = con.execute(
        "INSERT INTO sweeps (name, spec, folder, started_at, runs) "
        "VALUES (?, ?, ?, datetime('now'), ?)",
        (name, spec, folder, runs),
    )
    con.commit()
    return int(cur.lastrowid or 0)


def finish_sweep(con: sqlite3.Connection, sweep_id: int) -> None:
    """Record that a sweep ran to its end."""
    con.execute("UPDATE sweeps SET finished_at = datetime('now') WHERE id = ?", (sweep_id,))
    con.commit()


def last_sweep(con: sqlite3.Connection) -> tuple[str, str, str, bool] | None:
    """(name, spec text, folder, finished) of the latest sweep recorded, if any."""
    row = con.execute(
        "SELECT name, spec, folder, finished_at FROM sweeps ORDER BY id DESC LIMIT 1"
    ).fetchone()
    if row is None:
        return None
    return row[0], row[1], row[2], row[3] is not None


def rows(con: sqlite3.Connection, where: str = "", params: Iterable[Any] = ()) -> list[dict]:
    """All runs (or those matching ``where``) as dicts, JSON columns decoded."""
    cur = con.execute(f"SELECT * FROM runs {where} ORDER BY id", tuple(params))
    names = [d[0] for d in cur.description]
    out = []
    for values in cur:
        r = dict(zip(names, values, strict=True))
        for c in JSON_COLUMNS:
            if r.get(c) is not None:
                r[c] = json.loads(r[c])
        out.append(r)
    return out
