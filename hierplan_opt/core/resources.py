"""What this process uses of memory and what it may use: limits, the machine's memory.

The memory watch of long searches (:meth:`.timer.Deadline.keep_back_heap`) and the
memory budget of the formulations (:mod:`hierplan_opt.formulations.memory`) read these.
"""

from __future__ import annotations

import math

#: A search that calls :meth:`.Deadline.keep_back_heap` stops, as at its time limit, when
#: the process comes within this many bytes of its memory limit (``RLIMIT_DATA``, which
#: ``hierplan solve --memory-limit`` sets, or ``RLIMIT_AS``, which ``hierplan sweep``'s
#: workers set): room for the allocations between two measurements (CBS on
#: empty-32-32-even-1 k200 grows by about 100 MB a second) and for building its result.
#: It also stops when the machine (or the container) has less than this left: a search
#: that a program runs without any limit ends with its bound, not in the kernel's
#: out-of-memory killer.
MEMORY_MARGIN = 256 << 20

_STATUS_FIELDS = {"VmData:": 0, "VmSize:": 1}


def memory_use() -> tuple[int, int]:
    """Bytes of this process's data segment and address space (what ``RLIMIT_DATA``
    and ``RLIMIT_AS`` limit); zeros where unknown.

    Example
    -------
    >>> data, space = memory_use()
    >>> 0 <= data <= space
    True
    """
    out = [0, 0]
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                i = _STATUS_FIELDS.get(line[:7])
                if i is not None:
                    out[i] = int(line.split()[1]) * 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    return out[0], out[1]


def data_size() -> int:
    """Bytes of this process's data segment (what ``RLIMIT_DATA`` limits); 0 if unknown."""
    return memory_use()[0]


def memory_limits() -> tuple[float, float]:
    """The process's soft ``RLIMIT_DATA`` and ``RLIMIT_AS`` in bytes (``inf``: none).

    Example
    -------
    >>> all(x > 0 for x in memory_limits())
    True
    """
    try:
        import resource  # POSIX only (see the except)
    except ImportError:  # pragma: no cover - not on POSIX
        return math.inf, math.inf
    out: list[float] = []
    for which in (resource.RLIMIT_DATA, resource.RLIMIT_AS):
        soft = resource.getrlimit(which)[0]
        out.append(math.inf if soft == resource.RLIM_INFINITY else float(soft))
    return out[0], out[1]


def meminfo() -> dict[str, int]:
    """``/proc/meminfo`` in bytes (empty off Linux).

    Example
    -------
    >>> "MemTotal" in meminfo()
    True
    """
    out: dict[str, int] = {}
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                key, _, rest = line.partition(":")
                parts = rest.split()
                if parts and parts[0].isdigit():
                    out[key] = int(parts[0]) * 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    return out


def _cgroup_file(name_v2: str, name_v1: str) -> int | None:
    for path in (f"/sys/fs/cgroup/{name_v2}", f"/sys/fs/cgroup/memory/{name_v1}"):
        try:
            with open(path, encoding="ascii") as f:
                text = f.read().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 60:
            return int(text)
    return None


def cgroup_limit() -> int | None:
    """The container's (cgroup's) memory limit in bytes, None without one."""
    return _cgroup_file("memory.max", "memory.limit_in_bytes")


def _cgroup_inactive_file() -> int:
    """The container's reclaimable page cache (``inactive_file``), 0 if unknown."""
    for path, key in (
        ("/sys/fs/cgroup/memory.stat", "inactive_file"),
        ("/sys/fs/cgroup/memory/memory.stat", "total_inactive_file"),
    ):
        try:
            with open(path, encoding="ascii") as f:
                for line in f:
                    name, _, value = line.partition(" ")
                    if name == key and value.strip().isdigit():
                        return int(value)
        except OSError:
            continue
    return 0


def memory_available() -> float:
    """Bytes the machine can still give (``MemAvailable``), or the container if it has
    less left below its limit (its usage less the page cache it can drop, as ``docker
    stats`` counts it); ``inf`` where unknown.

    Example
    -------
    >>> memory_available() > 0
    True
    """
    avail = float(meminfo().get("MemAvailable", math.inf))
    limit = cgroup_limit()
    if limit is not None:
        used = _cgroup_file("memory.current", "memory.usage_in_bytes")
        if used is not None:
            avail = min(avail, float(limit - used + _cgroup_inactive_file()))
    return avail
