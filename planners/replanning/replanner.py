"""Replanning in flight: re-optimise the rest of the motion and splice it into the plan in force.

The thesis ends on making the optimisation fast enough to plan online; this module does it on a
receding horizon. At a trigger (an event that changes the mission, a tracking error past a bound, or
a fixed rate, decided by the caller: :mod:`fpr.sim.replanning`) at time t_0, :meth:`Replanner.replan`
builds and solves the NLP of :class:`planners.problem.motion.MotionProblem` for the motion from the *splice*
t_s = t_0 + deadline to the end of the horizon:

* the start point at t_s is the plan in force's own [s, s', s'', s''', s''''] at t_s: the splice is C4,
  so the planned rotor speeds, which depend on s up to its 4th derivative through the roll acceleration,
  do not jump. (A ``start`` off the plan, e.g. from the robot's state, can be solved, to time it, but is
  not spliced in: the plan in force would jump there, and :class:`~planners.trajectory.polynomial.PiecewisePolynomial`
  holds C4 motions only);
* then the way points still ahead, up to ``horizon`` travels past the last one that changed (or the
  end, or the ``through`` way point), with the mission's via points inside each travel (the travel cut by
  t_s keeps them in proportion to its rest, rounded, at least one when it is the whole horizon: a short rest
  split by via points gave degree-9 segments of 0.35 s that the 7-node grid holds at the nodes while the
  rotor speeds between them broke their limits by 10-60 rad/s);
  their values are fixed (moved way points at their new place), their derivatives 1..4 and every via
  point free, as in the 1-step method (seed 3.2.4);
* the end of the horizon keeps the plan in force's jet (C4 with the rest of it), or rest at the end;
* the same objective as the offline plan (alpha, and the offline normalisation J_e0, J_phi0 of the
  mission's stop motion, 3.26) and the same constraints (margins, rolls, rotor speeds 3.48), solved from
  the plan in force by :func:`planners.replanning.solver.solve_warm` (an explicit iteration cap); the result is
  checked on a dense grid (:func:`planners.problem.disturbance.dense_check`, the rows of
  :func:`planners.problem.report.evaluate_motion`);
* gusts the replanner was told of (:meth:`Replanner.learn`) are in the inverse dynamics of the NLP and of
  the check (:class:`planners.problem.disturbance.DisturbedProblem`).

**Deadline.** The solve must end before t_s in simulated time. Its wall time is measured on the
machine and reported, but by default (``timing = "work"``) the used / not-used decision compares the
deadline with a deterministic latency: the solver's work (derivative and value evaluations times grid
nodes) times a cost per unit of work measured on this machine (:data:`WORK_COST`), so that the same
command gives the same bytes. ``timing = "wall"`` compares the measured wall time instead (not
reproducible bit for bit). A plan that is late or infeasible is not used: the plan in force stays, and
the :class:`Replan` record says why.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from fpr.model.errors import PlannerArgumentError
from planners.problem.disturbance import CONTROL_HEADROOM, RISE, DisturbedProblem, dense_check
from planners.missions.events import moved_positions
from planners.methods.way_points import WayPointTask
from planners.trajectory.polynomial import N_DERIVS, PiecewisePolynomial
from planners.problem.motion import MotionProblem
from planners.replanning.check import evaluate_and_check
from planners.replanning.solver import solve_warm
from planners.optimisation.solving import Grid

#: Cost of the solver's work for the deterministic latency [s]: (per derivative evaluation per grid node,
#: per value evaluation per grid node, per second of re-optimised motion: the dense check and the set-up).
#: Fitted (non-negative least squares) by ``python -m fpr.bench --section replan``, which prints the fit
#: and the ratio of this model to the measured latency. The value in use is the fit of a slow machine (one
#: BLAS thread, nothing else running), so that a replan the model calls on time is on time there too. With
#: it the built-in moving-target replan (21 nodes, one derivative evaluation; the cut travel keeps only via
#: points leaving segments as long as the offline plan's, :meth:`Replanner._layout`) is modelled at 46.2 ms,
#: within the default 50 ms deadline. Refit it on another machine (documentation: guides/replanning).
WORK_COST = (2.2e-3, 0.0, 0.0)
TIMINGS = ("work", "wall")


@dataclass(frozen=True)
class ReplanOptions:
    """How :class:`Replanner` replans.

    Attributes:
        deadline: simulated time between the trigger and the splice, within which the solve must end [s].
        horizon: travels re-optimised past the last way point that changed (or past the next one).
        max_iterations: SQP iteration cap of one replan (:func:`planners.replanning.solver.solve_warm`).
        tolerance: the SQP stops when an iteration improves J by less than this.
        samples_per_segment, windows_per_segment: the optimisation grid: 7 nodes per segment (the offline
            planner uses 17); the dense check at ``dense_rate`` decides feasibility.
        dense_rate: rate of the dense check of the new part [Hz] (plus its knots; documentation, guides/replanning: why 100 Hz).
        radius: the SQP's initial trust region (x's scaled units).
        timing: ``"work"`` (deterministic latency from the solver's work, :data:`WORK_COST`) or ``"wall"``
            (the measured wall time) for the used / not-used decision.
        work_cost: the costs of the ``"work"`` latency model [s] (:data:`WORK_COST`).
        fuse_check: the dense check of the SQP's last trial point shares its inverse-dynamics call
            (:func:`planners.replanning.check.evaluate_and_check`; same verdict), or (False) is a call of its own.
        wind_headroom: w_h [rad/s], the least rotor speed the NLP asks for while a known gust pushes
            (:data:`planners.problem.disturbance.CONTROL_HEADROOM`; the check that decides use keeps w >= 0).
        refine_margin: an SQP iteration after the first (a refinement: the first gives a plan) starts only
            if ``refine_margin`` times the deterministic latency (:meth:`Replanner.latency`) with its
            evaluations is within the deadline: the work model has been up to 1.7 times below the measured
            latency (1 / 0.58, documentation: guides/replanning), and optional work must not make the plan late.
            0: every iteration up to ``max_iterations`` whatever the deadline (the replanner before the
            latency work); values in (0, 1) are refused (a refinement could then make an on-time plan late).
    """

    deadline: float = 0.05
    horizon: int = 1
    max_iterations: int = 2
    tolerance: float = 1e-3
    samples_per_segment: int = 7
    windows_per_segment: int = 4
    dense_rate: float = 100.0
    timing: str = "work"
    work_cost: tuple = WORK_COST
    radius: float = 0.3
    fuse_check: bool = True
    refine_margin: float = 1.7
    wind_headroom: float = CONTROL_HEADROOM

    def __post_init__(self):
        if not (np.isfinite(self.deadline) and self.deadline > 0):
            raise PlannerArgumentError(
                "deadline", self.deadline, f"deadline = {self.deadline!r}: give a time > 0 [s]"
            )
        if not (isinstance(self.horizon, int) and self.horizon >= 1):
            raise PlannerArgumentError(
                "horizon", self.horizon, f"horizon = {self.horizon!r}: give an integer >= 1"
            )
        if not (isinstance(self.max_iterations, int) and self.max_iterations >= 1):
            raise PlannerArgumentError(
                "max_iterations", self.max_iterations,
                f"max_iterations = {self.max_iterations!r}: give an integer >= 1",
            )
        if not (isinstance(self.refine_margin, (int, float)) and not isinstance(self.refine_margin, bool)
                and np.isfinite(self.refine_margin) and (self.refine_margin == 0 or self.refine_margin >= 1)):
            raise PlannerArgumentError(
                "refine_margin", self.refine_margin,
                f"refine_margin = {self.refine_margin!r}: give 0 (refine up to max_iterations) or a finite "
                "number >= 1 (below 1 a refinement could make an on-time plan late)",
            )
        if not isinstance(self.fuse_check, bool):
            raise PlannerArgumentError(
                "fuse_check", self.fuse_check, f"fuse_check = {self.fuse_check!r}: give True or False"
            )
        if not (isinstance(self.wind_headroom, (int, float)) and not isinstance(self.wind_headroom, bool)
                and np.isfinite(self.wind_headroom) and self.wind_headroom >= 0):
            raise PlannerArgumentError(
                "wind_headroom", self.wind_headroom,
                f"wind_headroom = {self.wind_headroom!r}: give a rotor speed >= 0 [rad/s] "
                "(0: the thesis' w >= 0)",
            )
        for name in ("radius", "dense_rate", "tolerance"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise PlannerArgumentError(name, value, f"{name} = {value!r}: give a finite number > 0")
        if self.timing not in TIMINGS:
            raise PlannerArgumentError(
                "timing", self.timing, f"timing = {self.timing!r}: use one of {TIMINGS}"
            )


@dataclass
class Replan:
    """One replan, as ``replans.json`` lists it.

    Attributes:
        time: the trigger's time t_0 [s]; splice_time: t_s = t_0 + deadline [s].
        trigger: what asked for it ("event: way point 2 moved", "tracking error ...", "rate").
        solve_wall_s: measured wall time of the solve and its dense check [s].
        latency_s: the latency compared with the deadline [s] (the work model's, or the wall time).
        deadline_s: the deadline [s].
        iterations: SQP iterations; n_variables: size of the NLP.
        J: objective of the re-optimised part on its grid (3.26, the offline normalisation).
        feasible: the re-optimised part holds every constraint on the dense grid.
        used: it was spliced into the plan; why: one line saying why (not) used.
        violated: the constraints it breaks (dense grid).
        start: "plan" (the plan in force's jet) or "robot" (a start from the robot's state).
        solver: why the SQP stopped (:func:`planners.replanning.solver.solve_warm`'s message).
        work: what the deterministic latency counts: grid ``nodes``, ``derivative_evaluations``,
            ``value_evaluations``, ``horizon_s`` (the re-optimised duration [s]).
    """

    time: float
    trigger: str
    splice_time: float
    solve_wall_s: float = 0.0
    latency_s: float = 0.0
    deadline_s: float = 0.0
    iterations: int = 0
    n_variables: int = 0
    J: float = float("nan")
    feasible: bool = False
    used: bool = False
    why: str = ""
    violated: list = field(default_factory=list)
    start: str = "plan"
    solver: str = ""
    work: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-friendly."""
        return dict(vars(self))


def jet(trajectory: PiecewisePolynomial, t: float) -> np.ndarray:
    """[s, s', s'', s''', s''''] of ``trajectory`` at t [s], shape (5, n) (held at rest past its end)."""
    return trajectory.evaluate_held(np.array([t]), order=N_DERIVS - 1)[:, 0, :]


def splice(
    before: PiecewisePolynomial,
    t_s: float,
    part: PiecewisePolynomial,
    after: PiecewisePolynomial | None = None,
    t_end: float | None = None,
) -> PiecewisePolynomial:
    """``before`` up to t_s, then ``part`` (starting at t_s), then ``after`` from t_end (if given).

    ``before`` is cut exactly: its segment through t_s is replaced by the degree-9 Hermite segment
    between its own points at the segment's start and at t_s, which is the same polynomial (10 conditions
    fix it). Knots of ``before`` / ``after`` closer than 1e-9 s to t_s / t_end are used as they are.
    """
    knots = before.knots
    a = int(np.searchsorted(knots, t_s + 1e-9, side="right") - 1)
    points, durations = list(before.points[: a + 1]), list(before.durations[:a])
    if t_s - knots[a] > 1e-9:
        points.append(jet(before, t_s))
        durations.append(t_s - knots[a])
    points += list(part.points[1:])
    durations += list(part.durations)
    if after is not None and t_end is not None and t_end < after.total_duration - 1e-9:
        b = int(np.argmin(np.abs(after.knots - t_end)))
        points += list(after.points[b + 1 :])
        durations += list(after.durations[b:])
    return PiecewisePolynomial(np.array(points), np.array(durations))


class Replanner:
    """Re-optimises the rest of a planned way-point mission while it is flown.

    Args:
        result: the offline :class:`planners.result.PlanResult` (its mission, robot and trajectory).
        options: :class:`ReplanOptions`.

    Attributes:
        trajectory: the plan in force (the executed plan so far, then its future), absolute time [s].
        way_positions: the way points in planning coordinates, moved ones at their new place (k, n_s).
        way_times: when the plan passes each way point [s] (k,).
        changed: index of the last way point moved since the plan in force was made, or None.
        replans: every :class:`Replan`, in order.
        revisions: (splice time [s], the plan in force from then on) of every replan used, in order.

    Raises:
        WorkspaceError, SingularityError: a move event's ``to`` out of the workspace
            (:func:`planners.missions.events.moved_positions`).
    """

    def __init__(self, result, options: ReplanOptions | None = None):
        self.options = options or ReplanOptions()
        self.mission, self.robot = result.mission, result.robot
        self.trajectory = result.trajectory
        task = WayPointTask.of(self.mission, self.robot)
        self.way_positions = np.array(self.mission.positions(self.robot), dtype=float)
        self.way_times = np.concatenate([[0.0], np.cumsum(self.mission.times)])
        self.n_via = np.asarray(task.n_via, dtype=int)
        self.grid = Grid(self.options.samples_per_segment, self.options.windows_per_segment)
        self.normalisation = task.normalisation(self.grid)
        self.moves = moved_positions(self.mission, self.robot)
        self.changed: int | None = None
        self.gusts: list = []
        self._learnt: set[int] = set()
        self._assumed = None
        self.replans: list[Replan] = []
        self.revisions: list[tuple[float, PiecewisePolynomial]] = []

    def move(self, event_index: int) -> None:
        """Apply the move event ``mission.events[event_index]``: its way point is at its new place."""
        event = self.mission.events[event_index]
        self.way_positions[event.way_point] = self.moves[event_index]
        self.changed = max(event.way_point, self.changed or 0)

    def learn(self, event_index: int) -> None:
        """The gust event ``mission.events[event_index]`` is known from now on: plans fly against it."""
        if event_index not in self._learnt:  # by index: a mission may list the same gust twice
            self._learnt.add(event_index)
            self.gusts.append(self.mission.events[event_index])

    def assume(self, gust) -> None:
        """Plan against ``gust`` (a :class:`planners.missions.events.GustEvent`, e.g. estimated in flight) from now on.

        It replaces the gust assumed before, which is kept in :attr:`gusts` but ends where ``gust`` is fully
        on (``gust.at + gust.rise``; the two blend over the ramp): the record of the wind each part of the
        plan was made for, against which the executed plan is checked. The gusts learnt from the mission stay.
        """
        if self._assumed is not None:
            self._end_assumed(gust.at + gust.rise)
        self.gusts.append(gust)
        self._assumed = gust

    def forget(self, t: float) -> None:
        """Stop planning against the assumed gust: it ramps down from t [s] (fully off at t + its rise)."""
        if self._assumed is not None:
            self._end_assumed(t + self._assumed.rise)
            self._assumed = None

    def _end_assumed(self, end: float) -> None:
        old = self._assumed
        if end < old.at + old.duration:
            shorter = dataclasses.replace(old, duration=max(end - old.at, 0.0))
            self.gusts = [shorter if g is old else g for g in self.gusts]

    @property
    def assumed(self):
        """The gust given by :meth:`assume` (e.g. the wind estimated in flight), or None."""
        return self._assumed

    def _gusts_within(self, begin: float, end: float) -> tuple:
        return tuple(g for g in self.gusts if g.at < end and g.at + g.duration + RISE > begin)

    def _layout(self, t_s: float, j0: int, j_end: int):
        """Knot times and the way-point flag of the horizon t_s -> way point j_end."""
        times, is_way = [t_s], [False]
        for j in range(j0, j_end + 1):
            begin = max(self.way_times[j - 1], t_s)
            n = int(self.n_via[j - 1])
            if begin > self.way_times[j - 1]:
                # the rest of a travel cut by the splice keeps the via points that leave its segments at
                # least as long as the offline plan's (shorter segments make the degree-9 polynomials
                # wiggle between the grid nodes, and each one costs the solve nodes), at least one when
                # it is all the horizon holds
                rest = (self.way_times[j] - begin) / (self.way_times[j] - self.way_times[j - 1])
                n = max(min(n, int(np.floor(rest * (n + 1) + 1e-9)) - 1), 1 if j0 == j_end else 0)
            times += list(begin + (self.way_times[j] - begin) * np.arange(1, n + 1) / (n + 1))
            times.append(self.way_times[j])
            is_way += [False] * n + [True]
        return np.array(times), np.array(is_way)

    def problem(self, t_s: float, start: np.ndarray | None = None, through: int | None = None):
        """The horizon's NLP from t_s (see the module docstring), or None when no way point is ahead.

        ``through``: re-optimise at least up to this way point (index; e.g. the travel after the next way
        point, re-planned in a known wind while the splice is still before that way point).

        Returns:
            (problem, x0, times, j_end) or None.
        """
        ahead = np.flatnonzero(self.way_times > t_s + 1e-6)
        if ahead.size == 0:
            return None
        j0 = int(ahead[0])
        k = len(self.way_times)
        if self.changed is not None and self.changed >= j0:  # through the moved way point, horizon travels on
            j_end = min(k - 1, self.changed + self.options.horizon)
        else:  # horizon travels from the robot's
            j_end = min(k - 1, j0 + self.options.horizon - 1)
        if through is not None:
            j_end = max(j_end, min(k - 1, int(through)))
        times, is_way = self._layout(t_s, j0, j_end)
        current = self.trajectory
        points = np.moveaxis(current.evaluate_held(times, order=N_DERIVS - 1), 0, 1).copy()  # (m+1, 5, n)
        # first guess: the plan in force, shifted by the way points' moves (linear in time between them)
        delta = (
            self.way_positions[j0 - 1 : j_end + 1]
            - np.moveaxis(current.evaluate_held(self.way_times[j0 - 1 : j_end + 1], order=0), 0, 1)[:, 0]
        )
        delta[0] = 0.0  # nothing moves behind the robot
        anchors = np.concatenate([[t_s], self.way_times[j0 : j_end + 1]])
        for c in range(points.shape[2]):
            points[:, 0, c] += np.interp(times, anchors, delta[:, c])
        points[0] = jet(current, t_s) if start is None else start
        if j_end == len(self.way_times) - 1:
            points[-1, 1:] = 0.0  # the mission ends at rest
        free = np.zeros(points.shape, dtype=bool)
        free[1:-1] = True
        free[1:-1, 0][is_way[1:-1]] = False  # way points keep their value
        gusts = self._gusts_within(t_s, float(times[-1]))
        kind, extra = MotionProblem, {}
        if gusts:
            kind = DisturbedProblem
            extra = {"gusts": gusts, "start_time": t_s, "headroom": self.options.wind_headroom}
        problem = kind(
            self.robot,
            points,
            np.diff(times),
            free,
            self.mission.alpha,
            self.normalisation,
            samples_per_segment=self.grid.samples_per_segment,
            windows_per_segment=self.grid.windows_per_segment,
            **extra,
        )
        return problem, problem.x_of(points), times, j_end

    def latency(self, work: dict) -> float:
        """The deterministic latency of a solve [s] from its ``work`` (:class:`Replan`, :data:`WORK_COST`)."""
        per_grad, per_value, per_second = self.options.work_cost
        return (
            work["nodes"]
            * (per_grad * work["derivative_evaluations"] + per_value * work["value_evaluations"])
            + per_second * work["horizon_s"]
        )

    def replan(
        self, t_0: float, trigger: str, start: np.ndarray | None = None, through: int | None = None
    ) -> Replan:
        """Re-optimise from t_s = t_0 + deadline, and splice the result in when it is feasible and on time.

        Args:
            t_0: the trigger's time [s].
            trigger: what asked for it (logged).
            start: the start point [s, s', ..., s''''] at t_s (5, n_s), or None for the plan in force's;
                a start off the plan in force is solved (timed) but never used (the splice must be C4).
            through: re-optimise at least up to this way point (:meth:`problem`), or None (the horizon).

        Returns:
            the :class:`Replan` record (also appended to :attr:`replans`); when ``used``,
            :attr:`trajectory` is the new plan in force.
        """
        opt = self.options
        t_s = t_0 + opt.deadline
        record = Replan(
            t_0, trigger, t_s, deadline_s=opt.deadline, start="plan" if start is None else "robot"
        )
        self.replans.append(record)
        begin = time.perf_counter()
        built = self.problem(t_s, start, through)
        if built is None:
            record.why = "not used: no way point ahead of the splice"
            return record
        problem, x0, times, j_end = built
        gusts = getattr(problem, "gusts", ())  # those the horizon's NLP flies in (problem)
        final = None
        if opt.fuse_check:
            final = lambda x: evaluate_and_check(problem, x, opt.dense_rate, t_s, gusts)  # noqa: E731
        horizon_s = float(times[-1] - times[0])

        def afford(gradients: int, values: int) -> bool:  # a refinement must not make the plan late
            work = {"nodes": problem.t.size, "derivative_evaluations": gradients, "value_evaluations": values,
                    "horizon_s": horizon_s}
            return opt.refine_margin * self.latency(work) <= opt.deadline

        out = solve_warm(
            problem, x0, opt.max_iterations, opt.tolerance, opt.radius, afford=afford, final=final
        )
        x = out.x
        part = PiecewisePolynomial(problem.points_of(x), problem.durations)
        if out.check is not None:  # the dense check came with the last evaluation
            feasible, violated, _ = out.check
        else:
            feasible, violated, _ = dense_check(self.robot, part, opt.dense_rate, t_s, gusts)
        record.solve_wall_s = time.perf_counter() - begin
        record.work = {
            "nodes": int(problem.t.size),
            "derivative_evaluations": int(out.gradient_evaluations),
            "value_evaluations": int(out.value_evaluations),
            "horizon_s": horizon_s,
        }
        modelled = self.latency(record.work)
        record.latency_s = modelled if opt.timing == "work" else record.solve_wall_s
        record.iterations, record.n_variables, record.J = out.iterations, problem.n_x, out.J
        record.solver = out.message
        record.feasible = bool(feasible)
        record.violated = list(violated)
        if out.message.startswith("QP failed"):
            record.why = f"not used: the solver failed ({out.message}); the plan in force stays"
        elif not record.feasible:
            record.why = f"not used: infeasible ({', '.join(record.violated)}); the plan in force stays"
        elif start is not None and not np.allclose(start, jet(self.trajectory, t_s), rtol=0.0, atol=1e-12):
            record.why = (
                "not used: its start is off the plan in force (the robot's state), and a splice must be "
                "C4; the plan in force stays"
            )
        elif record.latency_s > opt.deadline:
            record.why = (
                f"not used: late ({record.latency_s * 1e3:.1f} ms > deadline {opt.deadline * 1e3:.0f} ms, "
                f"{opt.timing}); the plan in force stays"
            )
        else:
            self.trajectory = splice(self.trajectory, t_s, part, self.trajectory, float(times[-1]))
            self.revisions.append((t_s, self.trajectory))
            self.changed = None if j_end >= (self.changed or 0) else self.changed
            record.used = True
            record.why = (
                f"used: spliced at {t_s:.3f} s, re-optimised up to way point {j_end} at {times[-1]:.3f} s"
            )
        return record


__all__ = ["Replan", "ReplanOptions", "Replanner", "TIMINGS", "WORK_COST", "jet", "splice"]
