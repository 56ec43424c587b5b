"""Closed-loop limits reported like planned ones: every planned constraint's worst margin in simulation.

A plan is checked on a dense grid (:func:`planners.problem.report.evaluate_motion`): every constraint of
:data:`planners.problem.motion.CONSTRAINT_KINDS` has a signed margin (>= 0 holds) against its **planning limit**,
which includes the design margins of the thesis (m_gd above the ground, m_ga from a singularity and from a
rolled-over drone, m_gr below w_max, seed 3.27-3.48) and, for a singularity crossing, the thrust floor.
The closed loop (:func:`fpr.sim.closed_loop.simulate`) does not follow the plan exactly, so the same
constraints are measured again on what the plant did, at every control tick, against two limits:

* the **planning limit**, as planned: a negative margin means the closed loop *ate into a design margin*;
  that is reported, not a failure (the margins exist for that);
* the **physical limit**, the same constraint with every design margin set to zero: the drone joints on
  the ground (z = -L), the chain's Type-2 singularity (q21 or q2 = 0 or pi), a drone rolled on its side
  (``|phi_i| = pi/2``), the rotor speeds 0 .. w_max, the fixed point's vertical (y = 0), and a thrust of 0 for
  the thrust floor. A negative margin there means the robot broke a physical limit: a failure (exit 1 of
  the command line, :mod:`fpr.cli.contract`).

What is measured: the chain coordinates s (or xi) of the plant, the drones' absolute rolls (the
``phi`` attitude coordinates), the rotor speeds of the plant (after the motor lag and the saturation to
[0, w_max]: a saturated rotor sits *at* its physical limit, margin 0, it never breaks it), and the
thrusts the allocation commands. For a singularity crossing the side of the crossing is the plant's own:
the time its chain crosses the singularity (once), not the planned time, so that a crossing a few
milliseconds late is not counted as a motion on the wrong side.

The margins are in the constraint's natural unit (m, rad, rad/s, N); a margin counts as broken below
``-FEASIBILITY_TOLERANCE[unit]`` (:mod:`planners.problem.report`), the plan's own tolerance.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pinocchio as pin

from fpr.model.errors import ModelArgumentError
from fpr.model.parameters import Margins
from planners.problem.motion import CONSTRAINT_KINDS, constraint_kind, constraint_rows
from planners.problem.report import FEASIBILITY_TOLERANCE

#: Entries of :meth:`fpr.sim.closed_loop.SimulationLog.summary` that depend on the wall clock.
WALL_CLOCK = ("wall_time_s", "real_time_factor")


@dataclass(frozen=True)
class ClosedLoopMargin:
    """The worst value of one planned constraint along a closed-loop run.

    Attributes:
        name: the constraint's name in the plan (``ground_2``, ``q1_high``, ``thrust_low_1``...).
        kind: its kind (key of :data:`planners.problem.motion.CONSTRAINT_KINDS`).
        unit: unit of the margins (m, rad, rad/s, N).
        planned: the plan's own worst margin against the planning limit (dense grid) [unit].
        margin_planning: the closed loop's worst margin against the planning limit [unit].
        time_planning: when it occurs [s].
        margin_physical: the closed loop's worst margin against the physical limit [unit].
        time_physical: when it occurs [s].
        design_margin: the planning limit's distance from the physical one at the worst sample
            (``margin_physical - margin_planning`` there: m_gd, m_ga, m_gr or the thrust floor) [unit].
        detail: which rotor or which side of a two-sided bound, at the physical worst.
    """

    name: str
    kind: str
    unit: str
    planned: float
    margin_planning: float
    time_planning: float
    margin_physical: float
    time_physical: float
    design_margin: float
    detail: str = ""

    @property
    def tolerance(self) -> float:
        """Largest violation still counted as holding [unit] (the plan's dense-grid tolerance)."""
        return FEASIBILITY_TOLERANCE[self.unit]

    @property
    def breaks_physical(self) -> bool:
        """The closed loop went past the physical limit: a failure."""
        return self.margin_physical < -self.tolerance

    @property
    def eats_design_margin(self) -> bool:
        """The closed loop went past the planning limit (into the design margin): reported, not a failure."""
        return self.margin_planning < -self.tolerance

    @property
    def state(self) -> str:
        """``ok``, ``margin eaten`` or ``BROKEN``."""
        return "BROKEN" if self.breaks_physical else "margin eaten" if self.eats_design_margin else "ok"

    def describe(self) -> str:
        """One line for people: both margins, when, and the plan's margin beside them."""
        extra = f", {self.detail}" if self.detail else ""
        return (f"{self.name:20s} {self.state:12s} planning limit {self.margin_planning:+.4g} {self.unit} at "
                f"t = {self.time_planning:.3f} s, physical limit {self.margin_physical:+.4g} {self.unit} at "
                f"t = {self.time_physical:.3f} s (planned {self.planned:+.4g}{extra})")

    def to_json(self) -> dict:
        """The entry of ``simulation.json``'s ``constraints``."""
        return {"margin_planning": self.margin_planning, "margin_physical": self.margin_physical,
                "unit": self.unit, "time_s": self.time_planning, "time_physical_s": self.time_physical,
                "planned_margin": self.planned, "design_margin": self.design_margin,
                "state": self.state, "detail": self.detail}


def physical_robot(robot):
    """A view of ``robot`` whose planning margins (m_gd, m_ga, m_gf, m_gr) are all zero: its constraint
    margins are those of the physical limits. The model, masses and rotor constants are shared.
    """
    bare = copy.copy(robot)
    bare.margins = Margins(ground=0.0, angle=0.0, force=0.0, rotor_speed=0.0)
    bare.kind = type(robot.kind)(bare)
    return bare


def thrust_floor(report) -> float | None:
    """The thrust floor f_min [N] a plan's dense-grid report was checked against (``thrust_low``), or None.

    It is read back from the report itself (the planned thrust minus the ``thrust_low`` margin at the
    worst sample), so any planner's floor is found without knowing how it was chosen.
    """
    for name, c in report.constraints.items():
        if c.kind == "thrust_low":
            drone = int(name.rsplit("_", 1)[1]) - 1
            k = int(np.argmin(np.abs(report.t - c.time)))
            return float(report.inputs.thrust[k, drone] - c.margin)
    return None


def _crossing_sign(robot, s, planned_time: float, t) -> np.ndarray:
    """Per sample +1 before the plant's chain crosses its singularity, -1 after, 0 at the crossing tick.

    The crossing is where the signed distance to the singularity (``crossing_side`` with sign +1) changes
    sign; with exactly one change that tick is used, otherwise (none, or several) the planned time.
    """
    side = np.real(robot.kind.crossing_margins(s, np.ones(len(s)))["crossing_side"])
    changes = np.flatnonzero(np.sign(side[1:]) * np.sign(side[:-1]) < 0)
    if changes.size == 1:
        k = changes[0] + (abs(side[changes[0] + 1]) < abs(side[changes[0]]))
        at = float(t[k])
    else:
        at = planned_time
    return np.sign(at - t) * (np.abs(t - at) > 1e-12)


class _Measured(SimpleNamespace):
    """What the plant did, as the kind's ``attitude_margins`` reads a plan's inputs: the drones' measured attitude
    coordinates (``roll``, ``attitude``), rotor speeds and allocated thrusts, and, computed when a kind reads it,
    ``thrust_vector``: each allocated thrust along the drone's measured thrust axis, in ``force_axes`` (N, n_d, k)
    [N] (Pinocchio's kinematics of the logged states).
    """

    def __init__(self, robot, log, **fields):
        super().__init__(**fields)
        self._robot, self._q = robot, log.q

    @property
    def thrust_vector(self) -> np.ndarray:
        robot = self._robot
        model, data = robot.model, robot.model.createData()
        rows = ["xyz".index(a) for a in robot.kind.force_axes]
        axes = np.empty((len(self._q), robot.n_drones, len(rows)))
        for k, q in enumerate(self._q):
            pin.framesForwardKinematics(model, data, robot.to_pinocchio(q))
            for i, frame in enumerate(robot.drone_frame_ids):
                axes[k, i] = data.oMf[frame].rotation[rows, 2]
        return self.thrust[..., None] * axes


def _rows(robot, log, crossing_sign, floor):
    """Constraint rows of the logged run (N, R), their names and details, for ``robot``'s limits."""
    index = {c: i for i, c in enumerate(log.coordinates)}
    s = log.q[:, [index[c] for c in log.chain]]
    rolls = log.q[:, [index[c] for c in robot.layout.rolls]]
    measured = _Measured(robot, log, roll=rolls, attitude=rolls.reshape(len(rolls), robot.n_drones, -1),
                         rotor_speed=log.speed, rotor_speed_squared=log.speed**2, thrust=log.thrust)
    motion = s[None]
    return constraint_rows(robot, motion, measured, scaled=False, crossing_sign=crossing_sign,
                           min_thrust=floor)


def _check(result, log) -> None:
    """Refuse a log of another robot, or an empty one."""
    robot = result.robot
    if log.robot_name != robot.name or tuple(log.chain) != tuple(robot.layout.chain):
        raise ModelArgumentError("log", log.robot_name, f"a log of the {log.robot_name} cannot be checked "
                                                        f"against a plan of the {robot.name}: simulate this plan")
    if log.t.size == 0:
        raise ModelArgumentError("log", "empty", "the log has no sample: nothing was simulated")


@dataclass(frozen=True)
class MarginSeries:
    """One planned constraint's closed-loop margins at every tick (the least over its rows: rotors, sides).

    Attributes:
        name, kind, unit: as in :class:`ClosedLoopMargin`.
        t: tick times (N,) [s].
        planning: margin to the planning limit (N,) [unit].
        physical: margin to the physical limit (N,) [unit].
        planned: the plan's own worst margin [unit].
    """

    name: str
    kind: str
    unit: str
    t: np.ndarray
    planning: np.ndarray
    physical: np.ndarray
    planned: float


def _per_constraint(result, log):
    """(name, rows against the planning limit, rows against the physical limit, details) of each planned
    constraint.
    """
    _check(result, log)
    robot = result.robot
    floor = thrust_floor(result.report)
    sign = None
    if result.crossing is not None:
        index = {c: i for i, c in enumerate(log.coordinates)}
        s = log.q[:, [index[c] for c in log.chain]]
        sign = _crossing_sign(robot, s, result.crossing.crossing_time, log.t)
    rows, names, details = _rows(robot, log, sign, floor)
    bare, _, _ = _rows(physical_robot(robot), log, sign, 0.0 if floor is not None else None)
    for name in dict.fromkeys(names):
        if name in result.report.constraints:
            cols = [c for c, n in enumerate(names) if n == name]
            yield name, rows[:, cols], bare[:, cols], [details[c] for c in cols]


def margin_series(result, log) -> dict[str, MarginSeries]:
    """Every planned constraint's margins at every tick of ``log``, against both limits (for figures).

    Args and raises: as :func:`closed_loop_margins`.
    """
    out = {}
    for name, plan_rows, phys_rows, _ in _per_constraint(result, log):
        kind = constraint_kind(name)
        out[name] = MarginSeries(name, kind, CONSTRAINT_KINDS[kind][0], log.t, plan_rows.min(axis=1),
                                 phys_rows.min(axis=1), float(result.report.constraints[name].margin))
    return out


def closed_loop_margins(result, log) -> dict[str, ClosedLoopMargin]:
    """Every constraint of the plan ``result``, measured on the closed-loop ``log`` against both limits.

    Args:
        result: the simulated :class:`planners.result.PlanResult` (its ``robot``, ``report`` and, for a
            crossing, ``crossing``).
        log: the :class:`fpr.sim.closed_loop.SimulationLog` of that plan (a run that lost the robot too: the
            margins then cover what was simulated).

    Returns:
        constraint name -> :class:`ClosedLoopMargin`, in the plan's order.

    Raises:
        ModelArgumentError: a log of another robot, or an empty log.
    """
    out = {}
    for name, plan_rows, phys_rows, details in _per_constraint(result, log):
        i, c = np.unravel_index(np.argmin(plan_rows), plan_rows.shape)
        j, d = np.unravel_index(np.argmin(phys_rows), phys_rows.shape)
        kind = constraint_kind(name)
        out[name] = ClosedLoopMargin(
            name, kind, CONSTRAINT_KINDS[kind][0], float(result.report.constraints[name].margin),
            float(plan_rows[i, c]), float(log.t[i]), float(phys_rows[j, d]), float(log.t[j]),
            float(phys_rows[j, d] - plan_rows[j, d]), details[d])
    return out


def broken(margins: dict) -> list[ClosedLoopMargin]:
    """The constraints whose physical limit the closed loop broke, worst (relative to tolerance) first."""
    bad = [m for m in margins.values() if m.breaks_physical]
    return sorted(bad, key=lambda m: m.margin_physical / m.tolerance)


def eaten(margins: dict) -> list[ClosedLoopMargin]:
    """The constraints whose design margin the closed loop ate into (physical limit kept), worst first."""
    bad = [m for m in margins.values() if m.eats_design_margin and not m.breaks_physical]
    return sorted(bad, key=lambda m: m.margin_planning / m.tolerance)


def margins_document(margins: dict) -> dict:
    """The JSON-friendly ``constraints`` of ``simulation.json``: name -> both margins, unit, times, state."""
    return {name: m.to_json() for name, m in margins.items()}


def simulation_document(log, margins: dict) -> dict:
    """``simulation.json``, the summary of ``simulation.npz``: the robot, the log's summary
    (:meth:`fpr.sim.closed_loop.SimulationLog.summary`), every planned constraint's closed-loop margins
    against both limits (``constraints``: name -> ``margin_planning``, ``margin_physical``, ``unit``,
    ``time_s``...),
    and the names of those whose physical limit was broken and those whose design margin was eaten. The
    wall-clock entries of the summary (:data:`WALL_CLOCK`) are left out, so that the file is byte-identical
    from one run to the next (the command line's ``manifest.json`` has the timings).
    """
    summary = {k: v for k, v in log.summary().items() if k not in WALL_CLOCK}  # same run, same bytes
    return {"robot": log.robot_name, "summary": summary, "constraints": margins_document(margins),
            "broken_physical": [m.name for m in broken(margins)],
            "design_margin_eaten": [m.name for m in eaten(margins)]}


def margin_lines(margins: dict) -> list[str]:
    """Lines for people: a heading, then one line per constraint (:meth:`ClosedLoopMargin.describe`)."""
    return ["closed-loop margins of the planned constraints (>= 0 holds; planning limit = with the design "
            "margins m_gd, m_ga, m_gr and the thrust floor, physical limit = without them):",
            *("  " + m.describe() for m in margins.values())]


def broken_message(margins: dict) -> str | None:
    """One line naming every broken physical limit with its margin and time, or None when none is broken."""
    bad = broken(margins)
    if not bad:
        return None
    names = ", ".join(f"{m.name} ({m.margin_physical:+.4g} {m.unit} past it at t = {m.time_physical:.3f} s)"
                      for m in bad)
    return (f"the simulated robot broke a physical limit: {names}; plan with more margin (longer --times, "
            "more --via-points) or a smaller disturbance")
