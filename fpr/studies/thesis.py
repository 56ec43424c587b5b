"""The thesis' planning studies with our parameters (seed 3.2.5, 3.2.6 and appendix).

Three studies, each a function that plans a few motions with :func:`planners.optimize.plan` and
returns a small frozen dataclass of numbers (with the :class:`~planners.optimize.PlanResult` objects
kept in ``plans`` for plots):

* :func:`via_point_study` (seed 3.2.5, Fig. 3.7-3.8): the ``study`` mission planned with
  n_vp = 0..4 via points per travel at alpha = 0.5. The thesis normalises by the *no-via-point*
  case: ``energy_ratio = J_e / J_e(n_vp = 0)``, ``perturbation_ratio = J_phi / J_phi(n_vp = 0)``.
  The stop-at-every-way-point motion (the J_e0, J_phi0 of eq. 3.26, i.e. J = 1) is reported too;
  on the single-travel ``study`` mission it is the n_vp = 0 motion itself.
* :func:`alpha_study` (seed 3.2.5, Fig. 3.9-3.10): the same mission with n_vp = 1 and
  alpha in {0, 0.3, 0.6, 0.9, 1}; ``energy_ratio = J_e / J_e|alpha=0`` and
  ``perturbation_ratio = J_phi / J_phi|alpha=1``, as the thesis defines them.
* :func:`method_comparison` (seed appendix, 1-step against 2-step; seed 3.2.6, Fig. 3.11-3.18,
  optimised against stop at way points): the ``square`` mission planned with ``"none"``,
  ``"two-step"`` and ``"one-step"``.

The two-step method is the thesis' own: the studies plan with ``polish=False`` (no final one-step solve
from the two-step result, :class:`planners.options.PlanOptions`) unless ``polish=True`` is given.

Every J_e, J_phi, J and feasibility flag is the dense-grid one of the :class:`PlanResult` (500 Hz,
exact |.| in J_e); J is normalised by the mission's stop-at-every-way-point motion (3.26). The
wall times include the dense-grid checks; they depend on the machine and its load.

The command line (``python -m fpr.studies``, :mod:`fpr.cli.studies`) runs the three studies, prints
their tables and writes their figures.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from fpr.model.errors import PlannerArgumentError, UnknownMethodError
from planners.methods import CROSSING_METHODS, METHODS
from planners.missions.mission import Mission, load_mission
from planners.optimize import plan
from planners.result import PlanResult

STUDY_MISSION = "study"
"""Built-in mission of the parameter studies (seed 3.2.5)."""
COMPARISON_MISSION = "square"
"""Built-in mission of the method comparison (seed 3.2.6 and appendix)."""
VIA_POINT_COUNTS = (0, 1, 2, 3, 4)
ALPHAS = (0.0, 0.3, 0.6, 0.9, 1.0)
COMPARED_METHODS = ("none",) + tuple(m for m in METHODS if m != "none" and m not in CROSSING_METHODS)
"""Every registered method that plans a way-point mission, stop at way points first."""

Progress = Callable[[str], None]


# ------------------------------------------------------------------------------------------ one case
@dataclass(frozen=True)
class Case:
    """The numbers of one planned motion.

    Attributes:
        label: e.g. ``"n_vp = 2"``, ``"alpha = 0.3"``, ``"two-step"``.
        method: ``"none"``, ``"two-step"`` or ``"one-step"``.
        via_points: via points per travel (the mission's, one per travel).
        alpha: energy weight of the objective.
        J: alpha J_e / J_e0 + (1 - alpha) J_phi / J_phi0 (3.26), normalised by the stop-at-way-points
            motion [-].
        J_e: energy index (3.24, exact |.|) [J].
        J_phi: perturbation index (3.25) [rad^2/s].
        J_e0, J_phi0: the same indices of the stop-at-every-way-point motion [J, rad^2/s].
        feasible: every constraint holds on the dense grid.
        solver_success: every NLP solve ended with its solver reporting success.
        wall_time: planning time, dense-grid checks included [s].
        iterations: solver iterations, summed over the NLP solves.
        evaluations: function evaluations (with and without derivatives), summed.
        peak_thrust: largest thrust of a drone [N].
        peak_rotor_speed: largest rotor speed [rad/s].
        least_rotor_speed: smallest signed rotor speed (negative: w^2 < 0, impossible) [rad/s].
        peak_roll: largest |roll| of a drone [rad].
        least_ground_clearance: least height of a drone joint above the ground [m].
        least_singularity_margin: least distance of q21 (q2) to 0 or pi [rad].
        violated: names of the violated constraints (dense grid), worst first.
        messages: one ``"<stage>: <solver message>"`` per NLP solve.
    """

    label: str
    method: str
    via_points: tuple[int, ...]
    alpha: float
    J: float
    J_e: float
    J_phi: float
    J_e0: float
    J_phi0: float
    feasible: bool
    solver_success: bool
    wall_time: float
    iterations: int
    evaluations: int
    peak_thrust: float
    peak_rotor_speed: float
    least_rotor_speed: float
    peak_roll: float
    least_ground_clearance: float
    least_singularity_margin: float
    violated: tuple[str, ...] = ()
    messages: tuple[str, ...] = ()

    @classmethod
    def of(cls, label: str, result: PlanResult) -> Case:
        """The numbers of ``result``."""
        peaks = result.report.peaks(result.robot)
        return cls(
            label=label, method=result.method, via_points=tuple(int(n) for n in result.mission.via_points),
            alpha=float(result.alpha), J=float(result.J), J_e=float(result.report.J_e),
            J_phi=float(result.report.J_phi), J_e0=float(result.reference.J_e),
            J_phi0=float(result.reference.J_phi), feasible=bool(result.feasible),
            solver_success=bool(result.solver_success), wall_time=float(result.wall_time),
            iterations=int(sum(s.iterations for s in result.stages)),
            evaluations=int(sum(s.evaluations for s in result.stages)),
            peak_thrust=peaks["peak_thrust_N"], peak_rotor_speed=peaks["peak_rotor_speed_rad_s"],
            least_rotor_speed=peaks["least_rotor_speed_rad_s"], peak_roll=peaks["peak_roll_rad"],
            least_ground_clearance=peaks["least_ground_clearance_m"],
            least_singularity_margin=peaks["least_singularity_margin_rad"],
            violated=tuple(c.name for c in result.report.violations),
            messages=tuple(f"{s.name}: {s.message}" for s in result.stages),
        )

    def to_dict(self) -> dict:
        """JSON-friendly copy (tuples become lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}


def _ratio(value: float, reference: float) -> float:
    return value / reference if reference != 0 else math.nan


def _say(progress: Progress | None, text: str) -> None:
    if progress is not None:
        progress(text)


def _run(label: str, mission: Mission, method: str, robot, progress: Progress | None, what: str,
         plan_options: Mapping) -> tuple[Case, PlanResult]:
    _say(progress, f"{what}: {label} ({method}) ...")
    plan_options = {"polish": False, **plan_options}  # the thesis' 2-step method (see the module docstring)
    result = plan(mission, method, robot=robot, **plan_options)
    case = Case.of(label, result)
    state = "feasible" if case.feasible else "INFEASIBLE (" + ", ".join(case.violated) + ")"
    _say(progress, f"{what}: {label}: J = {case.J:.4f}, J_e = {case.J_e:.4g} J, J_phi = {case.J_phi:.4g} "
                   f"rad^2/s, {state}, {case.iterations} iterations, {case.wall_time:.2f} s")
    return case, result


def _mission(mission: Mission | str | None, default: str) -> Mission:
    if mission is None:
        return load_mission(default)
    if isinstance(mission, str):
        return load_mission(mission)
    return mission


# ------------------------------------------------------------------------------------------ via points
class _CaseSeries:
    """What the studies share: per-case accessors and the table rows (subclasses hold ``cases``, ``stop``)."""

    @property
    def J(self) -> tuple[float, ...]:
        """J of each case (normalised by the stop-at-way-points motion, 3.26)."""
        return tuple(c.J for c in self.cases)

    @property
    def J_e(self) -> tuple[float, ...]:
        """J_e of each case [J]."""
        return tuple(c.J_e for c in self.cases)

    @property
    def J_phi(self) -> tuple[float, ...]:
        """J_phi of each case [rad^2/s]."""
        return tuple(c.J_phi for c in self.cases)

    @property
    def feasible(self) -> tuple[bool, ...]:
        """Dense-grid feasibility of each case."""
        return tuple(c.feasible for c in self.cases)

    @property
    def wall_time(self) -> tuple[float, ...]:
        """Planning time of each case [s]."""
        return tuple(c.wall_time for c in self.cases)

    def _rows(self, energy: tuple[str, Case], perturbation: tuple[str, Case]) -> list[dict]:
        """Rows of the stop motion and every case, with J_e and J_phi divided by the given references."""
        def row(label, case):
            return {"case": label, "J": case.J, "J_e [J]": case.J_e, "J_phi [rad^2/s]": case.J_phi,
                    energy[0]: _ratio(case.J_e, energy[1].J_e),
                    perturbation[0]: _ratio(case.J_phi, perturbation[1].J_phi),
                    "feasible": case.feasible, "iterations": case.iterations, "time [s]": case.wall_time}
        return [row("stop at way points", self.stop)] + [row(c.label, c) for c in self.cases]


@dataclass(frozen=True, eq=False)
class ViaPointStudy(_CaseSeries):
    """J_e and J_phi against the number of via points (seed 3.2.5, Fig. 3.7-3.8).

    Attributes:
        mission: name of the mission planned.
        method: the optimisation used.
        alpha: the energy weight used.
        counts: numbers of via points per travel, one per case.
        cases: the numbers of each case (:class:`Case`), in the order of ``counts``.
        energy_ratio: J_e / J_e(n_vp = 0), one per case (the thesis' normalisation) [-].
        perturbation_ratio: J_phi / J_phi(n_vp = 0), one per case [-].
        reference: the n_vp = 0 case the ratios divide by (planned even if 0 is not in ``counts``).
        stop: the stop-at-every-way-point motion (its J_e, J_phi are the J_e0, J_phi0 of 3.26).
        plans: the :class:`PlanResult` of each case (not compared, not printed).
    """

    mission: str
    method: str
    alpha: float
    counts: tuple[int, ...]
    cases: tuple[Case, ...]
    energy_ratio: tuple[float, ...]
    perturbation_ratio: tuple[float, ...]
    reference: Case
    stop: Case
    plans: tuple[PlanResult, ...] = field(default=(), repr=False)

    def rows(self) -> list[dict]:
        """Table rows: the stop-at-way-points motion, then one row per case."""
        return self._rows(("J_e/J_e(n_vp=0)", self.reference), ("J_phi/J_phi(n_vp=0)", self.reference))

    def to_dict(self) -> dict:
        """Numbers only, JSON-friendly."""
        return {"study": "via points (seed 3.2.5, Fig. 3.7-3.8)", "mission": self.mission,
                "method": self.method, "alpha": self.alpha, "counts": list(self.counts),
                "energy_ratio": list(self.energy_ratio),
                "perturbation_ratio": list(self.perturbation_ratio),
                "ratios_divide_by": "the n_vp = 0 case", "reference": self.reference.to_dict(),
                "stop": self.stop.to_dict(), "cases": [c.to_dict() for c in self.cases]}


def via_point_study(mission: Mission | str | None = None, counts: Sequence[int] = VIA_POINT_COUNTS,
                    alpha: float = 0.5, method: str = "two-step", *, robot=None,
                    progress: Progress | None = None, **plan_options) -> ViaPointStudy:
    """Plan ``mission`` with each number of via points in ``counts`` (seed 3.2.5, Fig. 3.7-3.8).

    Args:
        mission: a :class:`Mission` or a built-in name / file; default the built-in ``study`` mission.
        counts: numbers n_vp of via points per travel (integers >= 0, distinct).
        alpha: the energy weight (replaces the mission's).
        method: ``"two-step"`` or ``"one-step"`` (``"none"`` has no via points to place).
        robot: the robot (default ``mission.load_robot()``).
        progress: called with one line of text before and after each plan, or None.
        **plan_options: passed to :func:`planners.optimize.plan` (e.g. ``samples_per_segment``, ``solver``).

    Returns:
        the :class:`ViaPointStudy`; the ratios divide by the n_vp = 0 case, planned as well
        when 0 is not in ``counts``.

    Raises:
        PlannerArgumentError: empty, negative or repeated counts. Errors of :func:`~planners.optimize.plan`.
    """
    counts = tuple(int(n) for n in counts)
    if not counts or min(counts) < 0 or len(set(counts)) != len(counts):
        raise PlannerArgumentError("counts", counts,
                                   f"counts={counts!r}: give distinct numbers of via points >= 0")
    base = _mission(mission, STUDY_MISSION).replace(alpha=float(alpha))
    robot = robot or base.load_robot()
    what = "via-point study"
    stop_case, stop_plan = _run("stop at way points", base, "none", robot, progress, what, plan_options)
    done: dict[int, tuple[Case, PlanResult]] = {}
    for n in (counts if 0 in counts else (0,) + counts):
        done[n] = _run(f"n_vp = {n}", base.replace(via_points=n), method, robot, progress, what, plan_options)
    reference = done[0][0]
    cases = tuple(done[n][0] for n in counts)
    return ViaPointStudy(
        mission=base.name, method=method, alpha=float(alpha), counts=counts, cases=cases,
        energy_ratio=tuple(_ratio(c.J_e, reference.J_e) for c in cases),
        perturbation_ratio=tuple(_ratio(c.J_phi, reference.J_phi) for c in cases),
        reference=reference, stop=stop_case, plans=tuple(done[n][1] for n in counts),
    )


# ------------------------------------------------------------------------------------------ alpha
@dataclass(frozen=True, eq=False)
class AlphaStudy(_CaseSeries):
    """J_e and J_phi against the weight alpha (seed 3.2.5, Fig. 3.9-3.10).

    Attributes:
        mission: name of the mission planned.
        method: the optimisation used.
        via_points: via points per travel.
        alphas: the weights, one per case.
        cases: the numbers of each case (:class:`Case`), in the order of ``alphas``.
        energy_ratio: J_e / J_e|alpha=0, one per case [-].
        perturbation_ratio: J_phi / J_phi|alpha=1, one per case [-].
        energy_reference: the alpha = 0 case (planned even if 0 is not in ``alphas``).
        perturbation_reference: the alpha = 1 case (same).
        stop: the stop-at-every-way-point motion (J_e0, J_phi0 of 3.26).
        plans: the :class:`PlanResult` of each case.
    """

    mission: str
    method: str
    via_points: int
    alphas: tuple[float, ...]
    cases: tuple[Case, ...]
    energy_ratio: tuple[float, ...]
    perturbation_ratio: tuple[float, ...]
    energy_reference: Case
    perturbation_reference: Case
    stop: Case
    plans: tuple[PlanResult, ...] = field(default=(), repr=False)

    def rows(self) -> list[dict]:
        """Table rows: the stop-at-way-points motion, then one row per case."""
        return self._rows(("J_e/J_e|a=0", self.energy_reference),
                          ("J_phi/J_phi|a=1", self.perturbation_reference))

    def to_dict(self) -> dict:
        """Numbers only, JSON-friendly."""
        return {"study": "alpha (seed 3.2.5, Fig. 3.9-3.10)", "mission": self.mission, "method": self.method,
                "via_points": self.via_points, "alphas": list(self.alphas),
                "energy_ratio": list(self.energy_ratio), "perturbation_ratio": list(self.perturbation_ratio),
                "energy_ratio_divides_by": "J_e of the alpha = 0 case",
                "perturbation_ratio_divides_by": "J_phi of the alpha = 1 case",
                "energy_reference": self.energy_reference.to_dict(),
                "perturbation_reference": self.perturbation_reference.to_dict(),
                "stop": self.stop.to_dict(), "cases": [c.to_dict() for c in self.cases]}


def alpha_study(mission: Mission | str | None = None, alphas: Sequence[float] = ALPHAS, via_points: int = 1,
                method: str = "two-step", *, robot=None, progress: Progress | None = None,
                **plan_options) -> AlphaStudy:
    """Plan ``mission`` with each weight in ``alphas`` (seed 3.2.5, Fig. 3.9-3.10).

    Args:
        mission: a :class:`Mission` or a built-in name / file; default the built-in ``study`` mission.
        alphas: energy weights in [0, 1], distinct.
        via_points: via points per travel (replaces the mission's).
        method: ``"two-step"`` or ``"one-step"``.
        robot: the robot (default ``mission.load_robot()``).
        progress: called with one line of text before and after each plan, or None.
        **plan_options: passed to :func:`planners.optimize.plan`.

    Returns:
        the :class:`AlphaStudy`; the alpha = 0 and alpha = 1 cases the ratios divide by are
        planned as well when they are not in ``alphas``.

    Raises:
        PlannerArgumentError: empty or repeated alphas, or one outside [0, 1]. Errors of ``plan``.
    """
    alphas = tuple(float(a) for a in alphas)
    if not alphas or len(set(alphas)) != len(alphas) or not all(0.0 <= a <= 1.0 for a in alphas):
        raise PlannerArgumentError("alphas", alphas, f"alphas={alphas!r}: give distinct weights in [0, 1]")
    base = _mission(mission, STUDY_MISSION).replace(via_points=int(via_points))
    robot = robot or base.load_robot()
    what = "alpha study"
    stop_case, _ = _run("stop at way points", base, "none", robot, progress, what, plan_options)
    done: dict[float, tuple[Case, PlanResult]] = {}
    for a in alphas + tuple(a for a in (0.0, 1.0) if a not in alphas):
        done[a] = _run(f"alpha = {a:g}", base.replace(alpha=a), method, robot, progress, what, plan_options)
    e_ref, p_ref = done[0.0][0], done[1.0][0]
    cases = tuple(done[a][0] for a in alphas)
    return AlphaStudy(
        mission=base.name, method=method, via_points=int(via_points), alphas=alphas, cases=cases,
        energy_ratio=tuple(_ratio(c.J_e, e_ref.J_e) for c in cases),
        perturbation_ratio=tuple(_ratio(c.J_phi, p_ref.J_phi) for c in cases),
        energy_reference=e_ref, perturbation_reference=p_ref, stop=stop_case,
        plans=tuple(done[a][1] for a in alphas),
    )


# ------------------------------------------------------------------------------------------ methods
@dataclass(frozen=True, eq=False)
class MethodComparison:
    """Stop at way points, 2-step and 1-step on one mission (seed appendix; 3.2.6, Fig. 3.11-3.18).

    Attributes:
        mission: name of the mission planned.
        methods: the methods, one per case.
        cases: the numbers of each case (:class:`Case`).
        plans: the :class:`PlanResult` of each case.
    """

    mission: str
    methods: tuple[str, ...]
    cases: tuple[Case, ...]
    plans: tuple[PlanResult, ...] = field(default=(), repr=False)

    def case(self, method: str) -> Case:
        """The case of ``method``."""
        return self.cases[self.methods.index(method)]

    def plan(self, method: str) -> PlanResult:
        """The :class:`PlanResult` of ``method``."""
        return self.plans[self.methods.index(method)]

    def rows(self) -> list[dict]:
        """One table row per method."""
        return [{"method": c.method, "J": c.J, "J_e [J]": c.J_e, "J_phi [rad^2/s]": c.J_phi,
                 "J_e/J_e0": _ratio(c.J_e, c.J_e0), "J_phi/J_phi0": _ratio(c.J_phi, c.J_phi0),
                 "peak thrust [N]": c.peak_thrust, "peak rotor speed [rad/s]": c.peak_rotor_speed,
                 "least ground clearance [m]": c.least_ground_clearance,
                 "least singularity margin [rad]": c.least_singularity_margin,
                 "feasible": c.feasible, "iterations": c.iterations, "time [s]": c.wall_time}
                for c in self.cases]

    def to_dict(self) -> dict:
        """Numbers only, JSON-friendly."""
        return {"study": "methods (seed appendix; 3.2.6, Fig. 3.11-3.18)", "mission": self.mission,
                "methods": list(self.methods), "cases": [c.to_dict() for c in self.cases]}


def method_comparison(mission: Mission | str | None = None, methods: Sequence[str] = COMPARED_METHODS, *,
                      robot=None, progress: Progress | None = None, **plan_options) -> MethodComparison:
    """Plan ``mission`` with each method (seed appendix: 1-step vs 2-step; 3.2.6: vs stop at way points).

    Args:
        mission: a :class:`Mission` or a built-in name / file; default the built-in ``square`` mission
            (its own n_vp and alpha are used).
        methods: distinct names of :data:`planners.methods.METHODS` (default :data:`COMPARED_METHODS`:
            ``"none"``, ``"two-step"``, ``"one-step"``).
        robot: the robot (default ``mission.load_robot()``).
        progress: called with one line of text before and after each plan, or None.
        **plan_options: passed to :func:`planners.optimize.plan` (e.g. ``solver="slsqp"``).

    Raises:
        PlannerArgumentError: empty or repeated methods. UnknownMethodError: a method not in the registry.
    """
    methods = tuple(methods)
    if not methods or len(set(methods)) != len(methods):
        raise PlannerArgumentError("methods", methods, f"methods={methods!r}: give distinct methods")
    for m in methods:
        if m not in METHODS:
            raise UnknownMethodError(m, tuple(METHODS))
    base = _mission(mission, COMPARISON_MISSION)
    robot = robot or base.load_robot()
    runs = [_run(m, base, m, robot, progress, "method comparison", plan_options) for m in methods]
    return MethodComparison(mission=base.name, methods=methods, cases=tuple(c for c, _ in runs),
                            plans=tuple(p for _, p in runs))
