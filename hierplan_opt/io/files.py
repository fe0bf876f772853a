"""Safe file access shared by every reader and writer.

Inputs are untrusted: :func:`read_text` reads only regular files (a FIFO, a socket or a
device such as ``/dev/zero`` is refused at once, never waited on or read without end)
and at most :attr:`Limits.max_bytes` bytes. The other limits bound what a small file can
ask for: YAML nesting depth and alias expansion (checked by the YAML reader), grid cells
(checked by :func:`check_grid` before a grid is allocated) and plan steps (formats with
run-length encoding).

Outputs are checked before any work (:func:`check_output`) and written atomically
(:func:`write_text`, :func:`atomic_path`): a temporary file in the target's folder is
renamed over the target only when it is complete, so an interrupted or failed write
leaves no half-written file. Every ``OSError`` on output becomes an
:class:`~hierplan_opt.core.errors.OutputError` whose one-line message names the file.

The limits come from the environment (``HIERPLAN_MAX_INPUT_MB``,
``HIERPLAN_MAX_GRID_CELLS``) or the command line (``hierplan --max-input-mb N
--max-grid-cells N ...``); in code use :func:`input_limits`.

Example
-------
>>> import os, tempfile
>>> d = tempfile.mkdtemp()
>>> f = write_text(os.path.join(d, "a.txt"), "hello\\n")
>>> read_text(f)
'hello\\n'
>>> with input_limits(max_bytes=3):
...     read_text(f)
Traceback (most recent call last):
...
hierplan_opt.core.errors.InputError: ...a.txt: the file has 6 bytes, more than the input limit ...
"""

from __future__ import annotations

import contextlib
import math
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from hierplan_opt.core.errors import InputError, OutputError
from hierplan_opt.core.options import positive_amount

MB = 1 << 20
#: Peak bytes per grid cell while a grid graph is built (measured: about 320 on 2D and
#: 460 on 3D grids; adjacency, coordinates and the temporaries of the construction).
BYTES_PER_CELL = 500


def _env_int(name: str, default: int, scale: int = 1) -> int:
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    return positive_amount(text, name, scale)


@dataclass(frozen=True)
class Limits:
    """Bounds on what an input file may ask for.

    Attributes
    ----------
    max_bytes : int
        Largest input file read (default 64 MiB; ``HIERPLAN_MAX_INPUT_MB``).
    max_depth : int
        Deepest YAML/JSON nesting (default 64; real instance files need 6).
    max_alias_factor : int
        YAML aliases may expand a document to at most this many times its nodes
        (plus 10000), which stops "billion laughs" alias bombs.
    max_cells : int
        Largest grid, in cells (default 2**24; ``HIERPLAN_MAX_GRID_CELLS``); building
        a grid needs about :data:`BYTES_PER_CELL` bytes per cell.
    max_plan_steps : int
        Most path entries a run-length-encoded plan may expand to (default 2**25).
    """

    max_bytes: int = 64 * MB
    max_depth: int = 64
    max_alias_factor: int = 4
    max_cells: int = 1 << 24
    max_plan_steps: int = 1 << 25

    @classmethod
    def from_environment(cls) -> Limits:
        """The defaults, overridden by ``HIERPLAN_MAX_INPUT_MB`` / ``HIERPLAN_MAX_GRID_CELLS``."""
        base = cls()
        return replace(
            base,
            max_bytes=_env_int("HIERPLAN_MAX_INPUT_MB", base.max_bytes, MB),
            max_cells=_env_int("HIERPLAN_MAX_GRID_CELLS", base.max_cells),
        )


_current: Limits | None = None


def limits() -> Limits:
    """The limits in force (read from the environment on first use)."""
    global _current
    if _current is None:
        _current = Limits.from_environment()
    return _current


def set_limits(new: Limits) -> None:
    """Replace the limits in force (the CLI does this for ``--max-input-mb`` etc.)."""
    global _current
    for name in ("max_bytes", "max_depth", "max_alias_factor", "max_cells", "max_plan_steps"):
        value = getattr(new, name)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(f"limit {name} must be a positive integer, got {value!r}")
    _current = new


@contextlib.contextmanager
def input_limits(**changes: int) -> Iterator[Limits]:
    """Temporarily change some limits: ``with input_limits(max_bytes=1 << 30): ...``.

    Example
    -------
    >>> with input_limits(max_cells=100) as lim:
    ...     lim.max_cells
    100
    """
    before = limits()
    set_limits(replace(before, **changes))
    try:
        yield limits()
    finally:
        set_limits(before)


def size_text(n: float) -> str:
    """A byte count for people: ``'512 bytes'``, ``'64 MB'``, ``'4.7e+17 TB'``.

    Example
    -------
    >>> size_text(512), size_text(64 * MB), size_text(3.5e12)
    ('512 bytes', '64 MB', '3.18 TB')
    """
    if n < 1024:
        return f"{int(n)} bytes"
    for unit in ("KB", "MB", "GB"):
        n /= 1024
        if n < 1024:
            return f"{n:.3g} {unit}"
    return f"{n / 1024:.3g} TB"


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


# ---------------------------------------------------------------------- reading
def _open_regular(path: str | Path) -> tuple[int, os.stat_result]:
    """A descriptor of the regular file ``path`` and its ``fstat``, opened non-blocking
    (a FIFO is never waited on); anything else is refused with one line naming the file."""
    if str(path) == "":
        raise InputError("an input file name is empty")
    p = Path(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    flags |= getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(p, flags)
    except FileNotFoundError:
        raise InputError(f"{p}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{p}: is a directory, expected a file") from None
    except OSError as exc:
        raise InputError(f"{p}: cannot be read ({exc.strerror or exc})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise InputError(f"{p}: is a directory, expected a file")
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{p}: is {_kind(st.st_mode)}, not a regular file")
    except BaseException:
        os.close(fd)
        raise
    return fd, st


def read_head(path: str | Path, size: int) -> bytes:
    """The first ``size`` bytes (fewer if the file is shorter) of the regular file
    ``path``: what a reader sniffs to tell formats apart. Refuses exactly what
    :func:`read_bytes` refuses (a FIFO, a device, a directory, a missing file) and, like
    it, never blocks.

    Example
    -------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> read_head(write_text(os.path.join(d, "h.txt"), "hello"), 2)
    b'he'
    >>> os.mkfifo(os.path.join(d, "f"))
    >>> read_head(os.path.join(d, "f"), 2)
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: ...f: is a FIFO (named pipe), not a regular file
    """
    fd, _ = _open_regular(path)
    with os.fdopen(fd, "rb", buffering=0) as f:
        try:
            return f.read(size) or b""
        except OSError as exc:
            raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None


def read_bytes(path: str | Path) -> bytes:
    """The bytes of the regular file ``path``, at most ``limits().max_bytes`` of them.

    Refuses, with one line naming the file: a missing file, a directory, a FIFO, a
    socket, a device (``/dev/zero``, ``/dev/urandom``, also behind a symbolic link), an
    unreadable file and a file over the size limit. Never blocks: the file is opened
    non-blocking and checked with ``fstat`` before anything is read.

    Example
    -------
    >>> read_bytes("/dev/zero")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: /dev/zero: is a character device, not a regular file
    """
    p = Path(path)
    fd, st = _open_regular(path)
    with os.fdopen(fd, "rb", buffering=0) as f:
        cap = limits().max_bytes
        if st.st_size > cap:
            raise InputError(_too_big(p, st.st_size, cap))
        try:
            data = f.read(cap + 1)  # the file may grow while it is read
        except OSError as exc:
            raise InputError(f"{p}: cannot be read ({exc.strerror or exc})") from None
    if data is None:  # pragma: no cover - a regular file never answers "would block"
        raise InputError(f"{p}: cannot be read (no data)")
    if len(data) > cap:
        raise InputError(_too_big(p, None, cap))
    return data


def _too_big(p: Path, size: int | None, cap: int) -> str:
    has = f"has {size} bytes" if size is not None else "has more"
    return (
        f"{p}: the file {has}, more than the input limit of {size_text(cap)} "
        "(raise it with --max-input-mb or HIERPLAN_MAX_INPUT_MB)"
    )


def read_text(path: str | Path) -> str:
    """The UTF-8 text of the regular file ``path`` (see :func:`read_bytes`).

    Binary files (NUL bytes, invalid UTF-8) are refused as "not a text file". A
    byte-order mark is dropped.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "b.map")
    >>> _ = open(f, "wb").write(b"\\x00\\x01")
    >>> read_text(f)
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: ...b.map: not a text file (it contains NUL bytes)
    """
    data = read_bytes(path)
    if b"\x00" in data:
        raise InputError(f"{Path(path)}: not a text file (it contains NUL bytes)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{Path(path)}: not a text file (UTF-8 decoding failed: {exc.reason})"
        ) from None
    return text[1:] if text.startswith("\ufeff") else text


# ---------------------------------------------------------------------- sizes
def check_grid(dims: Sequence[int], where: str) -> None:
    """Refuse a grid whose size is over ``limits().max_cells``, before allocating it.

    ``where`` starts the message (``"file:line: "``-style context, may be empty).

    Example
    -------
    >>> check_grid([10**15, 10**15], "big.yaml:3: ")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: big.yaml:3: a ... grid has 1e+30 cells and would need ...
    """
    cells = math.prod(int(d) for d in dims)
    cap = limits().max_cells
    if cells <= cap:
        return
    shape = "x".join(str(int(d)) for d in dims)
    count = str(cells) if cells < 10**12 else f"{float(cells):.2g}"
    raise InputError(
        f"{where}a {shape} grid has {count} cells and would need about "
        f"{size_text(float(cells) * BYTES_PER_CELL)} of memory; the limit is {cap} cells "
        "(raise it with --max-grid-cells or HIERPLAN_MAX_GRID_CELLS)"
    )


# ---------------------------------------------------------------------- writing
def check_output(
    path: str | Path | None,
    *,
    what: str = "output",
    suffixes: Iterable[str] | None = None,
) -> Path:
    """Check before any work that ``path`` can be written; return it as a ``Path``.

    Refuses an empty name, a missing folder, a parent that is not a folder, a folder
    without write permission, an existing directory or non-regular file (``/dev/full``,
    a FIFO: an atomic write cannot replace them) and, with ``suffixes``, an extension
    not in that list. ``what`` names the option in messages (``"--out"``).

    Example
    -------
    >>> check_output("", what="--out")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OutputError: --out: the file name is empty
    >>> check_output("/nonexistent-folder/p.yaml", what="--out")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OutputError: --out /nonexistent-folder/p.yaml: the folder ... not exist
    """
    if path is None or str(path).strip() == "":
        raise OutputError(f"{what}: the file name is empty")
    p = Path(path)
    label = f"{what} {p}"
    if suffixes is not None:
        allowed = [s.lower() for s in suffixes]
        if p.suffix.lower() not in allowed:
            got = f"'{p.suffix}'" if p.suffix else "none"
            raise OutputError(f"{label}: unsupported extension {got} (use {', '.join(allowed)})")
    parent = p.parent if str(p.parent) else Path(".")
    try:
        pst = parent.stat()
    except FileNotFoundError:
        # a missing ancestor, or an ancestor that is a file
        anc = parent
        while not anc.exists() and anc != anc.parent:
            anc = anc.parent
        if anc.exists() and not anc.is_dir():
            raise OutputError(f"{label}: {anc} is a file, not a folder") from None
        raise OutputError(f"{label}: the folder {parent} does not exist") from None
    except NotADirectoryError:
        raise OutputError(f"{label}: {_file_ancestor(parent)} is a file, not a folder") from None
    except OSError as exc:
        raise OutputError(f"{label}: cannot use the folder {parent} ({exc.strerror})") from None
    if not stat.S_ISDIR(pst.st_mode):
        raise OutputError(f"{label}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{label}: the folder {parent} is not writable")
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return p
    except OSError as exc:
        raise OutputError(f"{label}: cannot write ({exc.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{label}: is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise OutputError(f"{label}: is {_kind(st.st_mode)}; write to a regular file")
    return p


def _file_ancestor(p: Path) -> Path:
    for anc in [p, *p.parents]:
        if anc.exists() and not anc.is_dir():
            return anc
    return p


def check_outputs(
    outputs: Iterable[tuple[str, str | Path | None, Iterable[str] | None]],
) -> None:
    """Check several outputs at once: ``[(option, path or None, suffixes or None), ...]``.

    ``None`` paths (options not given) are skipped; two options naming one file are
    refused.

    Example
    -------
    >>> check_outputs([("--out", "a.yaml", None), ("--dot", "a.yaml", [".dot"])])
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OutputError: --dot a.yaml: unsupported extension '.yaml' (use .dot)
    """
    seen: dict[str, str] = {}
    for what, path, suffixes in outputs:
        if path is None:
            continue
        p = check_output(path, what=what, suffixes=suffixes)
        key = os.path.abspath(p)
        if key in seen:
            raise OutputError(f"{what} {p}: the same file as {seen[key]}")
        seen[key] = what


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed to ``path``.

    The temporary file keeps the extension (so ``fig.savefig(tmp)`` picks the format).
    On an exception the temporary file is removed and ``path`` is untouched; an
    ``OSError`` becomes an :class:`OutputError` naming ``path``.

    Example
    -------
    >>> import os, tempfile
    >>> f = os.path.join(tempfile.mkdtemp(), "x.txt")
    >>> with atomic_path(f) as tmp:
    ...     _ = tmp.write_text("done")
    >>> open(f).read(), os.listdir(os.path.dirname(f))
    ('done', ['x.txt'])
    """
    p = Path(path)
    if str(path).strip() == "":
        raise OutputError("output: the file name is empty")
    folder = p.parent if str(p.parent) else Path(".")
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=p.suffix, dir=folder)
    except OSError as exc:
        raise OutputError(f"{p}: cannot write ({exc.strerror or exc})") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        _set_mode(tmp)
        os.replace(tmp, p)
    except OSError as exc:
        _remove(tmp)
        raise OutputError(f"{p}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        _remove(tmp)
        raise


def _set_mode(tmp: Path) -> None:
    """Give the new file the mode a plain ``open(..., "w")`` would (mkstemp uses 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)


def _remove(tmp: Path) -> None:
    with contextlib.suppress(OSError):
        tmp.unlink()


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`); return the path."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically; return the path.

    Example
    -------
    >>> write_text("/nonexistent-folder/x.txt", "a")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.OutputError: /nonexistent-folder/x.txt: cannot write (No such file ...)
    """
    return write_bytes(path, text.encode("utf-8"))


__all__ = [
    "BYTES_PER_CELL",
    "Limits",
    "atomic_path",
    "check_grid",
    "check_output",
    "check_outputs",
    "input_limits",
    "limits",
    "read_bytes",
    "read_head",
    "read_text",
    "set_limits",
    "size_text",
    "write_bytes",
    "write_text",
]
