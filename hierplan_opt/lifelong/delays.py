"""Delays drawn exactly as the Start-Kit's ``DelayGenerator`` draws them.

The Start-Kit seeds a ``std::mt19937`` with ``delayConfig.seed`` and, every tick, first
counts down each robot's remaining delay, then picks robots among those not delayed
(Bernoulli: each with probability ``pDelay``; Poisson: ``Poisson(teamSize * pDelay)``
of them, by ``std::shuffle``) and draws each a duration (uniform integer in
``[minDelay, maxDelay]``, or a Gaussian rounded and clamped). A robot picked at tick
``t`` with duration ``d`` is delayed on ticks ``t .. t+d-1`` and logged as ``[t, t+d]``.

The delays do not depend on what the robots do, so the same problem gives the same
delays to every planner. :class:`DelayStream` reproduces libstdc++'s (GCC 11 and later)
algorithms draw for draw: ``generate_canonical`` (two 32-bit words per double),
Lemire's nearly-divisionless ``uniform_int_distribution``, the polar Gaussian (a fresh
distribution per draw, as the Start-Kit constructs it), the multiplication method of
``poisson_distribution`` (means below 12) and the two-at-a-time ``std::shuffle``. A
Poisson mean of 12 or more uses libstdc++'s rejection method, which is not reproduced
here: those streams are drawn from the same distribution with numpy (``exact`` is then
False). :class:`ReplayDelays` replays the ``delayIntervals`` of a Start-Kit log instead.

Example
-------
>>> from hierplan_opt.io.lorr import DelayConfig
>>> s = DelayStream(DelayConfig(seed=0, min_delay=1, max_delay=4, p_delay=0.5), 3)
>>> [s.next_tick() for _ in range(3)]  # (robot, duration) events per tick
[[], [(2, 2)], []]
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hierplan_opt.io.lorr import DelayConfig

_TWO32 = 4294967296.0
_TWO64 = 18446744073709551616.0
_MASK32 = 0xFFFFFFFF
#: libstdc++ switches from the multiplication method to rejection at this Poisson mean.
POISSON_EXACT_BELOW = 12.0


def mt19937_key(seed: int) -> np.ndarray:
    """The 624-word state of ``std::mt19937(seed)`` (Matsumoto's ``init_genrand``)."""
    mt = [0] * 624
    mt[0] = seed & _MASK32
    for i in range(1, 624):
        mt[i] = (1812433253 * (mt[i - 1] ^ (mt[i - 1] >> 30)) + i) & _MASK32
    return np.array(mt, dtype=np.uint32)


class MT19937:
    """``std::mt19937`` (32-bit words), buffered through numpy's generator.

    Example
    -------
    >>> MT19937(5489).next()  # the C++ standard's check value is the 10000th: 4123659995
    3499211612
    """

    BLOCK = 4096

    def __init__(self, seed: int) -> None:
        self._bg = np.random.MT19937(0)
        self._bg.state = {
            "bit_generator": "MT19937",
            "state": {"key": mt19937_key(seed), "pos": 624},
        }
        self._buf: list[int] = []
        self._i = 0

    def next(self) -> int:
        """The next 32-bit word."""
        if self._i >= len(self._buf):
            self._buf = self._bg.random_raw(self.BLOCK).tolist()
            self._i = 0
        w = self._buf[self._i]
        self._i += 1
        return w

    def canonical(self) -> float:
        """``std::generate_canonical<double, 53>``: two words, rounded as libstdc++ does."""
        s = float(self.next()) + float(self.next()) * _TWO32
        r = s / _TWO64
        return r if r < 1.0 else math.nextafter(1.0, 0.0)

    def below(self, n: int) -> int:
        """A uniform integer in ``[0, n)`` (Lemire's method as in libstdc++'s ``_S_nd``)."""
        prod = self.next() * n
        low = prod & _MASK32
        if low < n:
            threshold = ((1 << 32) - n) % n
            while low < threshold:
                prod = self.next() * n
                low = prod & _MASK32
        return prod >> 32


class DelayStream:
    """The per-tick delay events of a ``delayConfig`` for ``n`` robots (see module doc)."""

    def __init__(self, config: DelayConfig, n: int) -> None:
        self.config = config
        self.n = n
        self.rng = MT19937(config.seed)
        self.remaining = [0] * n
        self.intervals: list[list[tuple[int, int]]] = [[] for _ in range(n)]
        self.tick = 0
        lam = n * config.p_delay
        self.exact = config.event_model == "bernoulli" or lam < POISSON_EXACT_BELOW
        self._np = np.random.default_rng(config.seed)
        self._lam_thr = math.exp(-lam)

    # -- libstdc++ distributions -------------------------------------------------
    def _duration(self) -> int:
        c = self.config
        if c.min_delay == c.max_delay:
            return c.min_delay
        if c.duration_model == "uniform":
            return c.min_delay + self.rng.below(c.max_delay - c.min_delay + 1)
        span = float(c.max_delay - c.min_delay)
        mean = c.min_delay + span * c.gauss_mean_ratio
        std = span * c.gauss_std_ratio
        if std <= 0.0:
            return min(max(_lround(mean), c.min_delay), c.max_delay)
        while True:  # Marsaglia's polar method; the second value is discarded
            x = 2.0 * self.rng.canonical() - 1.0
            y = 2.0 * self.rng.canonical() - 1.0
            r2 = x * x + y * y
            if 0.0 < r2 <= 1.0:
                break
        z = y * math.sqrt(-2.0 * math.log(r2) / r2)
        return min(max(_lround(z * std + mean), c.min_delay), c.max_delay)

    def _poisson(self) -> int:
        if not self.exact:
            return int(self._np.poisson(self.n * self.config.p_delay))
        x = 0
        prod = 1.0
        while True:
            prod *= self.rng.canonical()
            x += 1
            if not prod > self._lam_thr:
                return x - 1

    def _shuffle(self, items: list[int]) -> None:
        n = len(items)
        if n < 2:
            return
        below = self.rng.below
        i = 1
        if n % 2 == 0:
            j = below(2)
            items[i], items[j] = items[j], items[i]
            i += 1
        while i != n:
            b0 = i + 1
            b1 = b0 + 1
            x = below(b0 * b1)
            p1, p2 = divmod(x, b1)
            items[i], items[p1] = items[p1], items[i]
            i += 1
            items[i], items[p2] = items[p2], items[i]
            i += 1

    # -- one tick ----------------------------------------------------------------
    def next_tick(self) -> list[tuple[int, int]]:
        """Advance one tick; the new ``(robot, duration)`` delay events."""
        rem = self.remaining
        for a in range(self.n):
            if rem[a] > 0:
                rem[a] -= 1
        c = self.config
        picked: list[int] = []
        if c.event_model == "bernoulli":
            p = c.p_delay
            can = self.rng.canonical
            for a in range(self.n):
                if rem[a] == 0 and can() < p:
                    picked.append(a)
        else:
            free = [a for a in range(self.n) if rem[a] == 0]
            if free:
                k = min(self._poisson(), len(free))
                if k > 0:
                    self._shuffle(free)
                    picked = free[:k]
        events = []
        for a in picked:
            d = self._duration()
            rem[a] = d
            self.intervals[a].append((self.tick, self.tick + d))
            events.append((a, d))
        self.tick += 1
        return events

    def delayed(self, a: int) -> bool:
        """Whether robot ``a`` is delayed on the current tick (after :meth:`next_tick`)."""
        return self.remaining[a] > 0


class ReplayDelays(DelayStream):
    """The delays of a recorded run (its ``delayIntervals``), tick by tick.

    Example
    -------
    >>> r = ReplayDelays([[[1, 3]], []])
    >>> [(r.next_tick(), r.delayed(0)) for _ in range(4)]
    [([], False), ([(0, 2)], True), ([], True), ([], False)]
    """

    def __init__(self, intervals: Sequence[Sequence[Sequence[int]]]) -> None:
        self.n = len(intervals)
        self.remaining = [0] * self.n
        self.intervals = [[] for _ in range(self.n)]
        self.tick = 0
        self.exact = True
        self._starts: dict[int, list[tuple[int, int]]] = {}
        for a, ivs in enumerate(intervals):
            for s, e in ivs:
                self._starts.setdefault(int(s), []).append((a, int(e) - int(s)))

    def next_tick(self) -> list[tuple[int, int]]:
        """Advance one tick; the recorded events that start on it."""
        rem = self.remaining
        for a in range(self.n):
            if rem[a] > 0:
                rem[a] -= 1
        events = self._starts.get(self.tick, [])
        for a, d in events:
            rem[a] = d
            self.intervals[a].append((self.tick, self.tick + d))
        self.tick += 1
        return list(events)


def _lround(x: float) -> int:
    """C's ``lround``: halves away from zero."""
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


__all__ = ["MT19937", "DelayStream", "ReplayDelays", "mt19937_key"]
