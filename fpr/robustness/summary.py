r"""A campaign's results: the table of runs (``runs.parquet``) and its summary (``summary.json``).

The success rate comes with its 95 % Wilson score interval: the p whose score test does not reject the
observed x successes in n runs,

.. math::
    \frac{\hat p + z^2 / 2n \pm z \sqrt{\hat p (1 - \hat p) / n + z^2 / 4 n^2}}{1 + z^2 / n},
    \quad \hat p = x / n,\ z = 1.95996,

which, unlike the normal approximation, stays within [0, 1] and is not empty at 0 or n successes.
"""

from __future__ import annotations

import math
import re
from collections import Counter

import numpy as np

from fpr import extras

Z95 = 1.959963984540054
"""The standard normal's 97.5 % quantile."""


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a proportion (see the module docstring); (0, 1) for n = 0."""
    if n <= 0:
        return 0.0, 1.0
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


def table(rows: list[dict], columns: list[str]):
    """The rows as a ``pyarrow.Table``, one column per name, in that order (bool, int64, float64 or string).

    Raises:
        fpr.extras.MissingExtraError: pyarrow (the campaign extra) is not installed.
    """
    extras.require("campaign", ("pyarrow",))
    import pyarrow as pa

    arrays, fields = [], []
    for name in columns:
        values = [row.get(name) for row in rows]
        sample = next((v for v in values if v is not None), 0.0)
        if isinstance(sample, bool):
            kind = pa.bool_()
        elif isinstance(sample, str):
            kind = pa.string()
        elif isinstance(sample, int) and name in ("index", "saturated_ticks"):
            kind = pa.int64()
        else:
            kind, values = pa.float64(), [float("nan") if v is None else float(v) for v in values]
        arrays.append(pa.array(values, type=kind))
        fields.append(pa.field(name, kind))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


def write_table(path, rows: list[dict], columns: list[str]) -> None:
    """Write ``runs.parquet`` (the same rows give the same bytes), atomically."""
    import io

    import pyarrow.parquet as pq

    from fpr.files import write_atomic

    buffer = io.BytesIO()
    pq.write_table(table(rows, columns), buffer, compression="zstd")
    write_atomic(path, buffer.getvalue())


def failure_kind(line: str) -> str:
    """What a failure was, without its numbers: "tracking lost on y", "drone 2 hinge below the ground"..."""
    head = re.split(r" \(| at t =| between t =", line, maxsplit=1)[0]
    return head.strip() or line.strip()


def _distribution(values) -> dict:
    values = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    if not values.size:
        return {"count": 0}
    q = np.percentile(values, [0, 5, 50, 95, 100])
    return {"count": int(values.size), "min": float(q[0]), "p05": float(q[1]), "median": float(q[2]),
            "mean": float(values.mean()), "p95": float(q[3]), "max": float(q[4])}


def summarise(rows: list[dict], varied: list[str], outcomes: list[str]) -> dict:
    """The campaign's numbers: success rate and its 95 % Wilson interval, lost robots and errors by kind, the
    distribution (count, min, 5 %, median, mean, 95 %, max) of every varied value and numeric outcome.
    """
    n = len(rows)
    successes = sum(bool(r["success"]) for r in rows)
    low, high = wilson_interval(successes, n)
    lost = Counter(failure_kind(r["failure"]) for r in rows if r["lost"])
    errors = Counter(r["error"].split(":")[0] for r in rows if r["error"])
    numeric = [c for c in outcomes if c not in ("success", "lost", "failure", "error")
               and all(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool)
                       for r in rows if not r["error"] and r.get(c) is not None)]
    return {
        "runs": n,
        "successes": successes,
        "success_rate": successes / n if n else math.nan,
        "success_rate_wilson95": [low, high],
        "lost": sum(bool(r["lost"]) for r in rows),
        "lost_by_kind": dict(sorted(lost.items())),
        "errors": sum(bool(r["error"]) for r in rows),
        "errors_by_type": dict(sorted(errors.items())),
        "varied": {c: _distribution([r[c] for r in rows]) for c in varied},
        "outcomes": {c: _distribution([r[c] for r in rows if not r["error"]]) for c in numeric},
    }


def event_summary(rows: list[dict], family: str, without_observer: bool = False) -> dict:
    """The numbers of an event family's campaign (:mod:`fpr.robustness.outcomes`).

    Moves: the runs that passed (with the 95 % Wilson interval) and every miss with its reason. Gusts: those
    the robot cannot hold even as a steady force (:mod:`fpr.robustness.holding`) are counted apart, listed;
    over the others, the success rate (with and without the observer, each with its interval), the runs
    that broke a physical limit or had more than the allowed share of ticks saturated. Both: the replans'
    wall latency (count, median, p95, max), their CPU time and their modelled latency.
    """
    def rate(flags) -> dict:
        flags = [bool(f) for f in flags]
        low, high = wilson_interval(sum(flags), len(flags))
        return {"runs": len(flags), "successes": sum(flags),
                "success_rate": sum(flags) / len(flags) if flags else math.nan, "wilson95": [low, high]}

    out = {"family": family}
    counted = rows
    if family == "gust":
        apart = [r for r in rows if r.get("holdable") is False]
        counted = [r for r in rows if r.get("holdable") is not False]
        out["not_holdable"] = [{"index": r["index"], "body": r["gust_body"], "force_n": r["gust_force_n"],
                                "margin_rad_s": r["hold_margin_rad_s"]} for r in apart]
        out["broke_a_physical_limit"] = [r["index"] for r in counted if r.get("broken")]
        out["over_saturation"] = [r["index"] for r in counted if r.get("miss", "").startswith("saturated")]
    out["with_observer"] = rate(r["success"] for r in counted)
    if without_observer:
        out["without_observer"] = rate(r.get("no_observer_success") for r in counted)
        if family == "gust":
            out["without_observer"]["broke_a_physical_limit"] = [r["index"] for r in counted
                                                                 if r.get("no_observer_broken")]
    out["misses"] = [{"index": r["index"], "why": r.get("miss") or r.get("error") or "",
                      **({"way_point": r.get("event_way_point"), "pass_distance_m": r.get("pass_distance_m")}
                         if family == "move" else {"body": r.get("gust_body"), "force_n": r.get("gust_force_n")})}
                     for r in counted if not r["success"]]
    for key in ("replan_wall_s", "replan_cpu_s", "replan_latency_s"):
        out[key if key != "replan_latency_s" else "replan_modelled_s"] = _distribution(
            [w for r in rows for w in r.get(key) or []])
    return out


def broken_margins(row: dict, tracking: float = 0.05, speed_limit: float = 750.0, clearance: float = 0.1) -> dict:
    """Which margins a run broke: ``saturation`` (a rotor at a bound of the allocation), ``rotor speed`` (the
    plant's peak above ``speed_limit``, w_max - m_gr [rad/s]), ``tracking`` (a coordinate off the plan by more
    than ``tracking`` [m or rad]), ``ground`` (a drone's centre of mass closer than ``clearance`` to the
    ground [m]), ``lost``. A run that raised breaks none (its outcomes are unknown).
    """
    if row["error"]:
        return dict.fromkeys(("saturation", "rotor speed", "tracking", "ground", "lost"), False)
    worst = max(v for k, v in row.items() if k.startswith("max_error_"))
    return {"saturation": row["saturated_ticks"] > 0, "rotor speed": row["peak_rotor_speed_rad_s"] > speed_limit,
            "tracking": worst > tracking, "ground": row["least_clearance_m"] < clearance, "lost": bool(row["lost"])}


def first_breaks(rows: list[dict], column: str, **limits) -> dict:
    """For a sweep of ``column``: the least value at which each margin of :func:`broken_margins` breaks (None:
    it never does), so that the order of the values says which breaks first.
    """
    first = {}
    for row in sorted(rows, key=lambda r: r[column]):
        for name, broken in broken_margins(row, **limits).items():
            if broken and name not in first:
                first[name] = float(row[column])
    return {name: first.get(name) for name in ("saturation", "rotor speed", "tracking", "ground", "lost")}
