"""How the benchmark times things: :class:`Bench` (loops sized to a target duration, repeated, garbage
collector off; median and min per call), :func:`time_part` (only a part of each call timed) and
:func:`fmt` (durations for people).
"""

from __future__ import annotations

import gc
import itertools
import sys
import time

import numpy as np


def cycling(fn, args: list[tuple]):
    """A no-argument callable that calls fn on the next argument tuple of args, round robin."""
    pool = itertools.cycle(args)
    return lambda: fn(*next(pool))


class Bench:
    """Times items one after the other and keeps the results.

    Attributes:
        repeats: repeats of each timed loop.
        target: duration of one timed loop [s].
        progress: whether to print one line per item on stderr.
        results: one dict per item (name, median_s, min_s, n, per_sample_s, loops, repeats, ratio, ratio_to).
    """

    def __init__(self, repeats: int, target: float, progress: bool):
        self.repeats, self.target, self.progress = repeats, target, progress
        self.results: list[dict] = []

    @staticmethod
    def _loop(fn, loops: int) -> float:
        start = time.perf_counter()
        for _ in range(loops):
            fn()
        return time.perf_counter() - start

    def time(self, name: str, fn, n: int = 1, ref: tuple[str, ...] = ()) -> dict:
        """Time fn (one call handles n samples); ratio = per-sample time / sum of the refs' per-sample times."""
        fn()  # warm up (caches, lazy imports)
        gc.disable()
        try:
            loops, elapsed = 1, self._loop(fn, 1)
            while elapsed < self.target / 10:
                loops *= 4
                elapsed = self._loop(fn, loops)
            loops = max(1, round(loops * self.target / elapsed))
            per_call = sorted(self._loop(fn, loops) / loops for _ in range(self.repeats))
        finally:
            gc.enable()
        median = float(np.median(per_call))
        known = {r["name"]: r["per_sample_s"] for r in self.results}
        ratio = median / n / sum(known[r] for r in ref) if ref else None
        result = dict(name=name, median_s=median, min_s=per_call[0], n=n, per_sample_s=median / n, loops=loops,
                      repeats=self.repeats, ratio=ratio, ratio_to=" + ".join(ref) or None)
        self.results.append(result)
        if self.progress:
            print(f"bench [{len(self.results):2d}] {name}: {fmt(median)} per call", file=sys.stderr, flush=True)
        return result


def time_part(bench: Bench, name: str, prepare, part, n: int = 1) -> dict:
    """Like :meth:`Bench.time`, but only part() is timed; prepare() runs before each call, untimed.

    Each call's own time is summed (``time.perf_counter`` around it, ~50 ns of timer overhead included).
    """
    prepare()
    part()  # warm up
    gc.disable()
    try:
        def loop(count):
            total = 0.0
            for _ in range(count):
                prepare()
                start = time.perf_counter()
                part()
                total += time.perf_counter() - start
            return total

        loops, elapsed = 1, loop(1)
        while elapsed < bench.target / 10:
            loops *= 4
            elapsed = loop(loops)
        loops = max(1, round(loops * bench.target / elapsed))
        per_call = sorted(loop(loops) / loops for _ in range(bench.repeats))
    finally:
        gc.enable()
    median = float(np.median(per_call))
    result = dict(name=name, median_s=median, min_s=per_call[0], n=n, per_sample_s=median / n, loops=loops,
                  repeats=bench.repeats, ratio=None, ratio_to=None)
    bench.results.append(result)
    if bench.progress:
        print(f"bench [{len(bench.results):2d}] {name}: {fmt(median)} per call", file=sys.stderr, flush=True)
    return result


def fmt(seconds: float) -> str:
    """A duration with a readable unit."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if seconds >= scale:
            return f"{seconds / scale:7.3f} {unit}"
    return f"{seconds / 1e-9:7.1f} ns"
