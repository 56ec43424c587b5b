r"""The replanner's latency on the machine that runs it: a model calibrated by timing, and where it is kept.

A replan is used only when its solve is ready by the splice (:mod:`planners.replanning.replanner`). The
decision compares the time the solve has with a *modelled* latency, linear in the solver's work:

.. math:: \ell = c_0 + c_1\, g + c_2\, n g + c_3\, n v + c_4\, h

with g derivative evaluations and v value evaluations of the NLP (the dense check fused with the last
one), n grid nodes and h the re-optimised duration [s] (the set-up and the dense check grow with it).
The costs c are **measured on the machine**: :func:`planners.replanning.replanner.measure_latency` times whole
replans of a calibration mission of the robot (a square of 0.3 m or rad around the kind's ``reference_chain``
in joint space, flown with the stop-at-way-points plan) over a spread of horizons and iteration counts, each
replan three times (the median), and fits c by non-negative least squares. It takes one to two seconds.

**Determinism.** A decision that depends on a timing would make two runs differ. So the model a run uses
is read from a **per-machine calibration file** (:func:`default_path`: ``$FPR_CALIBRATION``, else
``$XDG_CACHE_HOME/fpr/replan-latency.json``, else ``~/.cache/fpr/replan-latency.json``), written once per
machine and robot, on first use (:func:`machine_latency`) or by ``python -m fpr.bench --section replan``,
and read back by every later run: on a given machine, with that file, the same command gives the same
bytes. The file says which machine measured it (host name, processor, core count); another machine's file
is measured again. A run can be pinned to any calibration by passing it explicitly (``python -m fpr.plan
--replan-calibration FILE``, a calibration file or a run's ``replans.json``, which records the model it
used): the same bytes on any machine.

**What it is not.** The model is the latency of a typical solve on an otherwise quiet machine (medians).
A loaded machine is slower: the bench prints the modelled latency against the measured one over its
replans, and the replanner keeps a safety factor on refinements (``ReplanOptions.refine_margin``).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fpr.files import write_atomic
from fpr.model.errors import PlannerArgumentError

logger = logging.getLogger(__name__)

#: The work features of the model, in the order of its costs (module docstring).
FEATURES = ("per solve", "per derivative evaluation", "per node and derivative evaluation",
            "per node and value evaluation", "per second re-optimised")
FORMAT = 1  # the calibration file's format


@dataclass(frozen=True)
class LatencyModel:
    """The modelled latency of a replan (module docstring).

    Attributes:
        costs: c_0 .. c_4 [s, s, s, s, s/s] (:data:`FEATURES`), each >= 0.
        source: where it came from (``"measured on this machine at <UTC time>"``, ``"given"``...).
    """

    costs: tuple
    source: str = "given"

    def __post_init__(self):
        costs = tuple(float(c) for c in self.costs)
        if len(costs) != len(FEATURES) or not all(math.isfinite(c) and c >= 0 for c in costs):
            raise PlannerArgumentError(
                "latency", self.costs,
                f"latency costs = {self.costs!r}: give {len(FEATURES)} finite numbers >= 0 [s] "
                f"({', '.join(FEATURES)})",
            )
        object.__setattr__(self, "costs", costs)

    @staticmethod
    def features(work: dict) -> np.ndarray:
        """The model's features of a solve's ``work`` (nodes, derivative and value evaluations, horizon_s)."""
        n, g, v = work["nodes"], work["derivative_evaluations"], work["value_evaluations"]
        return np.array([1.0, g, n * g, n * v, work["horizon_s"]], dtype=float)

    def latency(self, work: dict) -> float:
        """The modelled latency of a solve of this ``work`` [s]."""
        return float(np.dot(self.costs, self.features(work)))

    def to_dict(self) -> dict:
        """JSON-friendly (the costs as they are: ``json`` writes floats that read back to the same bits)."""
        return {"costs": list(self.costs), "features": list(FEATURES), "source": self.source}

    @classmethod
    def from_dict(cls, document: dict) -> LatencyModel:
        """The model of :meth:`to_dict`'s ``document`` (its costs and source: the same model whichever file it
        was read from, so that a run pinned to it writes the same bytes).
        """
        return cls(tuple(document["costs"]), str(document.get("source", "given")))


def machine() -> dict:
    """What identifies this machine in a calibration file: host name, processor, core count."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {"host": platform.node(), "processor": model, "cores": os.cpu_count() or 1}


def default_path() -> Path:
    """The per-machine calibration file (module docstring)."""
    given = os.environ.get("FPR_CALIBRATION")
    if given:
        return Path(given)
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(cache) / "fpr" / "replan-latency.json"


def read_calibration(path) -> dict:
    """The calibration file at ``path`` as a dict (``{}`` when absent or unreadable)."""
    try:
        document = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return document if isinstance(document, dict) else {}


def load_latency(path, robot_name: str) -> LatencyModel:
    """The model for ``robot_name`` from a calibration file, or from a run's ``replans.json`` (its
    ``latency_model``), to pin a run to it.

    Raises:
        PlannerArgumentError: a file that cannot be read, or holds no model for this robot.
    """
    path = Path(path)
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise PlannerArgumentError("calibration", str(path),
                                   f"cannot read the calibration file {path} ({error}): give a file written "
                                   "by python -m fpr.bench --section replan, or a run's replans.json"
                                   ) from None
    entry = None
    if isinstance(document, dict):
        entry = document.get("latency_model") or document.get("robots", {}).get(robot_name)
    try:
        return LatencyModel.from_dict(entry)
    except (TypeError, KeyError, PlannerArgumentError):
        raise PlannerArgumentError("calibration", str(path),
                                   f"{path} holds no replanning latency for the {robot_name!r} robot: give a "
                                   "calibration file of it, or a replans.json of one of its runs") from None


def write_calibration(path, robot_name: str, model: LatencyModel) -> None:
    """Add (replace) ``robot_name``'s model in the calibration file at ``path``, for this machine (atomic)."""
    path = Path(path)
    here = machine()
    document = read_calibration(path)
    if document.get("format") != FORMAT or document.get("machine") != here:
        document = {"format": FORMAT, "machine": here, "robots": {}}
    document["robots"][robot_name] = model.to_dict()
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, json.dumps(document, indent=1, sort_keys=True) + "\n")


def machine_latency(robot, measure, path=None) -> LatencyModel:
    """This machine's model for ``robot``: read from the calibration file, measured and written on first use.

    Args:
        robot: the robot (its ``name`` keys the file).
        measure: ``measure(robot) -> LatencyModel`` (:func:`planners.replanning.replanner.measure_latency`),
            called when the file has no model for this machine and robot; None: raise instead.
        path: the calibration file (default :func:`default_path`).

    Returns:
        the model, as read back from the file (the same bits whether it was just measured or not).

    Raises:
        PlannerArgumentError: no model for this machine and robot, and ``measure`` is False.
    """
    path = Path(path) if path is not None else default_path()
    document = read_calibration(path)
    entry = document.get("robots", {}).get(robot.name) if document.get("machine") == machine() else None
    if entry is None:
        if measure is None:
            raise PlannerArgumentError("calibration", str(path),
                                       f"{path} holds no replanning latency of the {robot.name!r} robot for "
                                       "this machine: run python -m fpr.bench --section replan")
        logger.warning("calibrating the replanner's latency on this machine for the %s robot (once; written "
                       "to %s)", robot.name, path)
        started = time.perf_counter()
        model = measure(robot)
        try:
            write_calibration(path, robot.name, model)
        except OSError as error:  # a read-only home: this run's own measurement, said so
            logger.warning("cannot write %s (%s): the latency measured now is used for this run only",
                           path, error)
            return dataclasses.replace(model, source=model.source + " (not written)")
        logger.info("calibrated in %.1f s", time.perf_counter() - started)
        entry = read_calibration(path)["robots"][robot.name]
    return LatencyModel.from_dict(entry)


__all__ = ["FEATURES", "LatencyModel", "default_path", "load_latency", "machine", "machine_latency",
           "read_calibration", "write_calibration"]
