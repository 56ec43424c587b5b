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

**Deadline and latency.** The solve must be ready by the splice, in simulated time. What it takes is the
*modelled* latency of :mod:`planners.replanning.latency`: the solver's work (evaluations times grid nodes,
the re-optimised duration) times costs measured on the machine that runs it, read from its calibration
file (``ReplanOptions.latency``), so that the same command gives the same bytes on that machine
(``timing = "wall"`` compares the measured wall time instead; not reproducible bit for bit).

A change is not dropped because it missed its first deadline. Before solving, the replanner models its
first iteration (one derivative and one value evaluation of the horizon's NLP); when that cannot be ready
by t_0 + deadline, the splice moves to the first time it can (rounded up to the millisecond, the horizon
rebuilt from there), and the record says so and why. Refinements (SQP iterations after the first) start
only when they fit the time to the splice with a margin (``refine_margin``): the best feasible iterate by
then is used. A solve found late all the same (the wall clock) is solved again at once with the splice
after its end. A part that breaks a constraint on the dense grid is not used: the plan in force stays,
and the :class:`Replan` record says which constraints; it is solved again at once with more SQP iterations
(``persist_iterations``), its splice as far as they take on this machine.
"""

from __future__ import annotations

import dataclasses
import datetime
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import nnls

from fpr.model.errors import PlannerArgumentError
from planners.methods.way_points import WayPointTask
from planners.missions.events import moved_positions
from planners.missions.mission import Mission
from planners.optimisation.solving import Grid
from planners.optimize import plan
from planners.problem.disturbance import CONTROL_HEADROOM, RISE, DisturbedProblem, dense_check
from planners.problem.motion import MotionProblem
from planners.replanning.check import evaluate_and_check
from planners.replanning.latency import FEATURES, LatencyModel, machine_latency
from planners.replanning.solver import solve_warm
from planners.trajectory.polynomial import N_DERIVS, PiecewisePolynomial

TIMINGS = ("work", "wall")


@dataclass(frozen=True)
class ReplanOptions:
    """How :class:`Replanner` replans.

    Attributes:
        deadline: simulated time between the trigger and the splice, within which the solve must end [s].
        horizon: travels re-optimised past the last way point that changed (or past the next one).
        least_horizon: a horizon shorter than this [s] takes the next travel too (a short rest of a travel
            alone gives a violent part: the splice's state must be brought to the way point in too little time).
        max_iterations: SQP iteration cap of one replan (:func:`planners.replanning.solver.solve_warm`).
        tolerance: the SQP stops when an iteration improves J by less than this.
        samples_per_segment, windows_per_segment: the optimisation grid: 7 nodes per segment (the offline
            planner uses 17); the dense check at ``dense_rate`` decides feasibility.
        dense_rate: rate of the dense check of the new part [Hz] (plus its knots; why 100 Hz:
            documentation, guides/replanning).
        radius: the SQP's initial trust region (x's scaled units).
        timing: ``"work"`` (the modelled latency of the solver's work, ``latency``) or ``"wall"`` (the
            measured wall time) for the used / not-used decision and the splice time.
        latency: the :class:`planners.replanning.latency.LatencyModel` of this machine, or None: read from
            the machine's calibration file, measured and written there on first use
            (:func:`planners.replanning.latency.machine_latency` with :func:`measure_latency`).
        fuse_check: the dense check of the SQP's last trial point shares its inverse-dynamics call
            (:func:`planners.replanning.check.evaluate_and_check`; same verdict), or (False) is a call of its own.
        wind_headroom: w_h [rad/s], the least rotor speed the NLP asks for while a known gust pushes
            (:data:`planners.problem.disturbance.CONTROL_HEADROOM`; the check that decides use keeps w >= 0).
        persist_iterations: a replan found infeasible is solved again at once (from when it ended) with up to
            this many SQP iterations, its splice put as far as they take on this machine; 0 (or no more than
            ``max_iterations``): not solved again.
        refine_margin: an SQP iteration after the first (a refinement: the first gives a plan) starts only
            if ``refine_margin`` times the modelled latency (:meth:`Replanner.latency`) with its
            evaluations is within the time to the splice: the model is a typical (median) solve, and
            optional work must not make the plan late. 0: every iteration up to ``max_iterations`` whatever
            the deadline; values in (0, 1) are refused (a refinement could then make an on-time plan late).
    """

    deadline: float = 0.05
    horizon: int = 1
    least_horizon: float = 1.0
    max_iterations: int = 2
    tolerance: float = 1e-3
    samples_per_segment: int = 7
    windows_per_segment: int = 4
    dense_rate: float = 100.0
    timing: str = "work"
    latency: LatencyModel | None = None
    radius: float = 0.3
    fuse_check: bool = True
    refine_margin: float = 1.7
    persist_iterations: int = 8
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
        if not (isinstance(self.persist_iterations, int) and not isinstance(self.persist_iterations, bool)
                and self.persist_iterations >= 0):
            raise PlannerArgumentError(
                "persist_iterations", self.persist_iterations,
                f"persist_iterations = {self.persist_iterations!r}: give an integer >= 0 (0: an infeasible "
                "replan is not solved again)",
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
        if not (isinstance(self.least_horizon, (int, float)) and not isinstance(self.least_horizon, bool)
                and np.isfinite(self.least_horizon) and self.least_horizon >= 0):
            raise PlannerArgumentError(
                "least_horizon", self.least_horizon,
                f"least_horizon = {self.least_horizon!r}: give a time >= 0 [s]",
            )
        for name in ("radius", "dense_rate", "tolerance"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise PlannerArgumentError(name, value, f"{name} = {value!r}: give a finite number > 0")
        if self.latency is not None and not isinstance(self.latency, LatencyModel):
            raise PlannerArgumentError(
                "latency", self.latency,
                f"latency = {self.latency!r}: give a planners.replanning.latency.LatencyModel, or None (this "
                "machine's calibration)",
            )
        if self.timing not in TIMINGS:
            raise PlannerArgumentError(
                "timing", self.timing, f"timing = {self.timing!r}: use one of {TIMINGS}"
            )


@dataclass
class Replan:
    """One replan, as ``replans.json`` lists it.

    Attributes:
        time: the trigger's time t_0 [s]; splice_time: t_s [s], t_0 + deadline, or later when the solve
            cannot be ready by then (``delayed_s``).
        trigger: what asked for it ("event: way point 2 moved", "tracking error ...", "rate").
        solve_wall_s: measured wall time of the solve and its dense check [s].
        solve_cpu_s: the process's CPU time over the same (one core's work: what the other jobs of a shared
            machine inflate the least) [s].
        latency_s: the latency compared with the time to the splice [s] (the model's, or the wall time).
        deadline_s: the deadline [s].
        delayed_s: how much later than t_0 + deadline the splice was put [s] (0: not delayed): the first
            iteration's modelled latency did not fit the deadline.
        iterations: SQP iterations; n_variables: size of the NLP.
        J: objective of the re-optimised part on its grid (3.26, the offline normalisation).
        feasible: the re-optimised part holds every constraint on the dense grid.
        used: it was spliced into the plan; why: one line saying why (not) used.
        violated: the constraints it breaks (dense grid).
        start: "plan" (the plan in force's jet) or "robot" (a start from the robot's state).
        solver: why the SQP stopped (:func:`planners.replanning.solver.solve_warm`'s message).
        work: what the modelled latency counts: grid ``nodes``, ``derivative_evaluations``,
            ``value_evaluations``, ``horizon_s`` (the re-optimised duration [s]).
        way_point: the last way point the re-optimised part reaches (index), or None.
    """

    time: float
    trigger: str
    splice_time: float
    solve_wall_s: float = 0.0
    solve_cpu_s: float = 0.0
    latency_s: float = 0.0
    deadline_s: float = 0.0
    delayed_s: float = 0.0
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
    way_point: int | None = None

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
        latency_model: the :class:`planners.replanning.latency.LatencyModel` the decisions use.

    Raises:
        WorkspaceError, SingularityError: a move event's ``to`` out of the workspace
            (:func:`planners.missions.events.moved_positions`).
    """

    def __init__(self, result, options: ReplanOptions | None = None):
        self.options = options or ReplanOptions()
        self.mission, self.robot = result.mission, result.robot
        self.latency_model = self.options.latency or machine_latency(self.robot, measure_latency)
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

    def assume(self, gusts) -> None:
        """Plan against ``gusts`` (a :class:`planners.missions.events.GustEvent` or a tuple of them, one per body
        it pushes, e.g. the wind estimated in flight) from now on.

        They replace the gusts assumed before, which are kept in :attr:`gusts` but end where the new ones are
        fully on (``at + rise``; the two blend over the ramp): the record of the wind each part of the plan
        was made for, against which the executed plan is checked. The gusts learnt from the mission stay.
        """
        gusts = (gusts,) if not isinstance(gusts, (tuple, list)) else tuple(gusts)
        if self._assumed is not None and gusts:
            self._end_assumed(gusts[0].at + gusts[0].rise)
        self.gusts.extend(gusts)
        self._assumed = gusts or None

    def forget(self, t: float) -> None:
        """Stop planning against the assumed gusts: they ramp down from t [s] (fully off at t + their rise)."""
        if self._assumed is not None:
            self._end_assumed(t + self._assumed[0].rise)
            self._assumed = None

    def _end_assumed(self, end: float) -> None:
        for old in self._assumed:
            if end < old.at + old.duration:
                shorter = dataclasses.replace(old, duration=max(end - old.at, 0.0))
                self.gusts = [shorter if g is old else g for g in self.gusts]

    @property
    def assumed(self) -> tuple | None:
        """The gusts given by :meth:`assume` (e.g. the wind estimated in flight), a tuple, or None."""
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
        while j_end < k - 1 and self.way_times[j_end] - t_s < self.options.least_horizon:
            j_end += 1
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
        """The modelled latency of a solve [s] from its ``work`` (:class:`Replan`, :attr:`latency_model`)."""
        return self.latency_model.latency(work)

    def replan(
        self, t_0: float, trigger: str, start: np.ndarray | None = None, through: int | None = None
    ) -> Replan:
        """Re-optimise from the splice t_s, and splice the result in when it is feasible and on time.

        t_s is t_0 + deadline, or the first time the solve's first iteration can be ready when that is later
        (module docstring). A solve late all the same (``timing = "wall"``) is solved again at once, with
        the splice after its end (a second record); so is an infeasible one, with up to ``persist_iterations``
        SQP iterations and the time they take on this machine (``refine_margin`` times their modelled
        latency) before its splice.

        Args:
            t_0: the trigger's time [s].
            trigger: what asked for it (logged).
            start: the start point [s, s', ..., s''''] at t_0 + deadline (5, n_s), or None for the plan in
                force's; a start off the plan in force is solved (timed) but never used (the splice must be C4).
            through: re-optimise at least up to this way point (:meth:`problem`), or None (the horizon).

        Returns:
            the :class:`Replan` record (also appended to :attr:`replans`; the last one when solved again);
            when ``used``, :attr:`trajectory` is the new plan in force.
        """
        record = self._replan(t_0, trigger, start, through)
        if record.why.startswith("not used: late") and start is None:
            again = f"{trigger} (again: the first solve was late)"
            record = self._replan(t_0 + record.latency_s, again, None, through)
        opt = self.options
        more = opt.persist_iterations
        if start is None and record.work and not record.feasible and more > opt.max_iterations \
                and not record.solver.startswith("QP failed"):
            # more SQP iterations, started when the first solve ends, with the time they take on this machine
            work = {**record.work, "derivative_evaluations": more, "value_evaluations": more}
            deadline = max(opt.deadline, opt.refine_margin * self.latency(work))
            self.options = dataclasses.replace(opt, max_iterations=more, deadline=deadline)
            try:
                again = f"{trigger} (again, up to {more} iterations: the first solve was infeasible)"
                record = self._replan(t_0 + record.latency_s, again, None, through)
            finally:
                self.options = opt
        return record

    def _first_ready(self, t_0: float, start, through):
        """The splice time and the horizon's NLP: t_0 + deadline, or later until the first iteration's
        modelled latency fits (rounded up to the ms); (t_s, built) with built as :meth:`problem` returns.
        """
        t_s = t_0 + self.options.deadline
        built = self.problem(t_s, start, through)
        for _ in range(4):  # a later splice shortens the horizon: a few rounds reach the fixed point
            if built is None or start is not None:
                break
            problem, _, times, _ = built
            first = self.latency({"nodes": problem.t.size, "derivative_evaluations": 1, "value_evaluations": 1,
                                  "horizon_s": float(times[-1] - times[0])})
            if first <= t_s - t_0 + 1e-12:
                break
            t_s = t_0 + math.ceil(first * 1e3 - 1e-9) * 1e-3
            built = self.problem(t_s, start, through)
        return t_s, built

    def _replan(self, t_0: float, trigger: str, start, through) -> Replan:
        opt = self.options
        begin, begin_cpu = time.perf_counter(), time.process_time()
        t_s, built = self._first_ready(t_0, start, through)
        record = Replan(
            t_0, trigger, t_s, deadline_s=opt.deadline, start="plan" if start is None else "robot",
            delayed_s=t_s - t_0 - opt.deadline if t_s > t_0 + opt.deadline + 1e-9 else 0.0,
        )
        self.replans.append(record)
        if built is None:
            record.why = "not used: no way point ahead of the splice"
            return record
        problem, x0, times, j_end = built
        record.way_point = int(j_end)
        available = t_s - t_0
        gusts = getattr(problem, "gusts", ())  # those the horizon's NLP flies in (problem)
        final = None
        if opt.fuse_check:
            final = lambda x: evaluate_and_check(problem, x, opt.dense_rate, t_s, gusts)  # noqa: E731
        horizon_s = float(times[-1] - times[0])
        nodes = int(problem.t.size)

        def afford(gradients: int, values: int) -> bool:  # a refinement must not make the plan late
            work = {"nodes": nodes, "derivative_evaluations": gradients, "value_evaluations": values,
                    "horizon_s": horizon_s}
            if opt.timing == "wall":  # what is spent, and the model's cost of one more iteration
                last = {**work, "derivative_evaluations": gradients - 1, "value_evaluations": values - 1}
                more = self.latency(work) - self.latency(last)
                return time.perf_counter() - begin + opt.refine_margin * more <= available
            return opt.refine_margin * self.latency(work) <= available

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
        record.solve_cpu_s = time.process_time() - begin_cpu
        record.work = {
            "nodes": nodes,
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
        delayed = ""
        if record.delayed_s > 0:
            delayed = (f" ({record.delayed_s * 1e3:.0f} ms past the {opt.deadline * 1e3:.0f} ms deadline: its "
                       f"first iteration needs up to {available * 1e3:.0f} ms on this machine)")
        if out.message.startswith("QP failed"):
            record.why = f"not used: the solver failed ({out.message}); the plan in force stays"
        elif not record.feasible:
            record.why = f"not used: infeasible ({', '.join(record.violated)}); the plan in force stays"
        elif start is not None and not np.allclose(start, jet(self.trajectory, t_s), rtol=0.0, atol=1e-12):
            record.why = (
                "not used: its start is off the plan in force (the robot's state), and a splice must be "
                "C4; the plan in force stays"
            )
        elif record.latency_s > available + 1e-12:
            record.why = (
                f"not used: late ({record.latency_s * 1e3:.1f} ms > {available * 1e3:.0f} ms to the splice, "
                f"{opt.timing}); the plan in force stays"
            )
        else:
            self.trajectory = splice(self.trajectory, t_s, part, self.trajectory, float(times[-1]))
            self.revisions.append((t_s, self.trajectory))
            self.changed = None if j_end >= (self.changed or 0) else self.changed
            record.used = True
            record.why = (
                f"used: spliced at {t_s:.3f} s{delayed}, re-optimised up to way point {j_end} at {times[-1]:.3f} s"
            )
        return record


def calibration_mission(robot) -> Mission:
    """The mission :func:`measure_latency` replans: a square of 0.3 (m or rad) in the first two chain
    coordinates around the robot kind's ``reference_chain``, in joint space, 2 s per travel.
    """
    s0 = np.array(robot.kind.reference_chain, dtype=float)
    e0 = np.eye(s0.size)[0] * 0.3
    e1 = np.eye(s0.size)[min(1, s0.size - 1)] * 0.3
    points = np.array([s0, s0 + e0, s0 + e0 + e1, s0 + e1, s0])
    mode = robot.kind.assembly_mode(s0) if robot.kind.assembly_modes else None
    return Mission(name="latency calibration", robot=robot.name, way_points=points, times=[2.0] * 4,
                   space="joint", arm=mode or "down")


def measure_latency(robot, repeats: int = 3) -> LatencyModel:
    """Time replans of :func:`calibration_mission` on this machine and fit the latency model's costs
    (:mod:`planners.replanning.latency`): 24 replans (4 splice times, 3 horizons, 1 or 2 SQP iterations),
    each timed ``repeats`` times (the median kept), fitted by non-negative least squares. One to two seconds.

    Args:
        robot: the robot whose replans are timed.
        repeats: timings of each replan.

    Returns:
        the :class:`planners.replanning.latency.LatencyModel`, its source "measured on this machine at <UTC
        time>".
    """
    result = plan(calibration_mission(robot), "none", robot=robot)
    free = LatencyModel((0.0,) * len(FEATURES), "calibration")  # no budget: every iteration asked for
    rows, walls = [], []
    for t in (0.3, 2.5, 4.9, 6.2):
        for through in (None, 3, 4):
            for iterations in (1, 2):
                options = ReplanOptions(max_iterations=iterations, refine_margin=0.0, latency=free)
                times = []
                for _ in range(repeats):
                    record = Replanner(result, options).replan(t, "calibration", through=through)
                    times.append(record.solve_wall_s)
                if record.work:
                    rows.append(LatencyModel.features(record.work))
                    walls.append(float(np.median(times)))
    costs = nnls(np.array(rows), np.array(walls))[0]
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    return LatencyModel(tuple(float(c) for c in costs), f"measured on this machine at {when}")


__all__ = ["Replan", "ReplanOptions", "Replanner", "TIMINGS", "calibration_mission", "jet", "measure_latency",
           "splice"]
