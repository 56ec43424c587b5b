"""``python -m fpr.plan --simulate --replan``: the options, the closed loop's hooks, the files of replanning.

* options (:mod:`fpr.cli.plan_options`): ``--replan``, ``--replan-deadline`` (default 0.05 s of simulated time),
  ``--replan-bound`` (tracking error that triggers a replan from the robot's state, default 0.05 m or rad),
  ``--replan-rate`` (an optional fixed rate [Hz]), ``--replan-wind`` (``known``, default: the replanner is told
  the force of each gust with a ``rise`` as it starts, a step gust stays unknown; ``estimated``: it plans
  against the controller's observer's estimate, or under ``--no-observer`` a steady wind estimated from the
  tracking error; ``blind``),
  ``--replan-timing`` (``work``: the modelled latency of the solver's work on this machine, default;
  ``wall``: the measured solve time, not reproducible bit for bit), ``--replan-calibration`` (the latency
  model: default this machine's calibration file, measured and written on first use; a file to pin a run
  to, e.g. an earlier run's ``replans.json``; ``measure``: timed at start, for this run only),
  ``--no-observer`` (the thesis' controller without the external-force observer, and the replanner's wind
  estimate from the tracking error);
* the simulation gets a :class:`fpr.sim.replanning.InFlight` when the mission has events or ``--replan``
  is given (gusts always push; ``move`` events need ``--replan``); each gust is checked before the flight:
  can the robot hold it at all, as a steady force within its rotor limits along the plan
  (:func:`fpr.robustness.holding.hold_check`, one line in the summary, and a warning on stderr when it cannot);
* files: ``replans.json`` (the latency model used; each replan: time, trigger, splice time, latency against
  the deadline, J, feasible, used or not and why; the executed plan's points and knots), the executed plan (the plan in
  force at each instant) in the planned columns of ``trajectory.csv``, and ``replanning.png``
  (:mod:`fpr.views.figures.replanning`). The solves' wall times go to ``manifest.json`` only.
"""

from __future__ import annotations

import dataclasses
import json
import sys

import numpy as np

from fpr.cli.checks import CommandLineError
from fpr.cli.text import length, plural
from fpr.model.errors import PlannerArgumentError
from fpr.robustness.holding import hold_check
from fpr.sim.replanning import InFlight, TriggerSettings
from fpr.views.figures.replanning import write_replanning_figure
from planners.missions.events import moved_positions
from planners.problem.disturbance import evaluate_in_gusts
from planners.replanning.latency import load_latency, machine_latency
from planners.replanning.replanner import Replanner, ReplanOptions, measure_latency


def check_options(args, mission, robot) -> None:
    """Refuse replanning options that cannot work, and moved way points out of reach (exit 2).

    The numbers of the replanning options are checked with the others (:mod:`fpr.cli.checks`).

    Raises:
        CommandLineError: --replan on a singularity-crossing mission; a --replan-calibration file that cannot
            be read or holds no model of the robot.
        WorkspaceError, SingularityError: a move event's ``to`` out of the workspace or on a singularity.
    """
    moved_positions(mission, robot)
    if getattr(args, "replan", False) and mission.cross_singularity:
        raise CommandLineError(
            "--replan",
            "",
            "a singularity-crossing mission cannot be replanned (its crossing "
            "is optimised as a whole): drop --replan",
        )
    calibration = getattr(args, "replan_calibration", None)
    if calibration not in (None, "measure"):
        try:
            load_latency(calibration, robot.name)
        except PlannerArgumentError as error:
            raise CommandLineError("--replan-calibration", calibration, error.reason) from None


def with_observer(args, settings):
    """The simulation ``settings`` with the controller's observer off under ``--no-observer``."""
    if not getattr(args, "no_observer", False):
        return settings
    return dataclasses.replace(settings, controller=dataclasses.replace(settings.controller, observer_bandwidth=0.0))


def in_flight(args, final, settings):
    """The closed loop's :class:`InFlight` for this run, or None (no events, no --replan); its ``verdicts``
    hold each gust's :func:`fpr.robustness.holding.hold_check` (by event index), made before the flight.
    """
    mission, robot = final.mission, final.robot
    replan = getattr(args, "replan", False)
    if not mission.events and not replan:
        return None
    verdicts = {i: hold_check(robot, mission, e) for i, e in enumerate(mission.events) if e.kind == "gust"}
    for i, verdict in verdicts.items():
        if not verdict.holdable and not getattr(args, "quiet", False):
            print(f"warning: gust {i}: {verdict.line()}", file=sys.stderr, flush=True)
    replanner = None
    if replan:
        options = ReplanOptions(deadline=args.replan_deadline, timing=args.replan_timing,
                                latency=latency_model(getattr(args, "replan_calibration", None), robot))
        replanner = Replanner(final, options)
    triggers = TriggerSettings(
        tracking_bound=args.replan_bound,
        rate=args.replan_rate,
        known_gusts=getattr(args, "replan_wind", "known") == "known",
        estimate_wind=getattr(args, "replan_wind", "known") == "estimated",
    )
    hooks = InFlight(
        mission, replanner, triggers, settings.controller, [robot.index[c] for c in robot.layout.chain], robot
    )
    hooks.verdicts = verdicts
    return hooks


def latency_model(calibration, robot):
    """The replanner's :class:`planners.replanning.latency.LatencyModel` for ``--replan-calibration``."""
    if calibration is None:
        return machine_latency(robot, measure_latency)
    if calibration == "measure":
        return measure_latency(robot)
    return load_latency(calibration, robot.name)


def executed(final, hooks):
    """The executed plan as a :class:`planners.result.PlanResult`, or None when nothing was replanned.

    The executed plan is the plan in force at each instant, checked on the dense grid (in the gusts the
    replanner was told of: :func:`planners.problem.disturbance.evaluate_in_gusts`).
    """
    if hooks is None or hooks.replanner is None or hooks.replanner.trajectory is final.trajectory:
        return None
    trajectory = hooks.replanner.trajectory
    ways = np.concatenate([[0.0], np.cumsum(final.mission.times)])
    is_way = np.array([bool(np.isclose(ways, k, atol=1e-9).any()) for k in trajectory.knots])
    gusts = tuple(hooks.replanner.gusts)  # the known gusts: the plan is checked in the wind it was made for
    report = evaluate_in_gusts(final.robot, trajectory, gusts, 500.0)
    return dataclasses.replace(final, trajectory=trajectory, is_way=is_way, report=report, stages=[])


def write(out, hooks, done, written, log=None, final=None) -> dict:
    """Write ``replans.json`` (and, given the log and the offline plan, ``replanning.png``).

    Returns:
        the solves' wall times for ``manifest.json`` (by ``replan i``) [s].
    """
    if hooks is None or hooks.replanner is None:
        return {}
    records = [r.to_dict() for r in hooks.replans]
    timings = {f"replan {i}": r.pop("solve_wall_s") for i, r in enumerate(records)}
    for r in records:  # machine-dependent: kept out of replans.json (the same command gives the same bytes)
        r.pop("solve_cpu_s")
    document = {
        "deadline_s": hooks.replanner.options.deadline,
        "timing": hooks.replanner.options.timing,
        "latency_model": hooks.replanner.latency_model.to_dict(),
        "replans": records,
        "used": sum(r["used"] for r in records),
        "executed_plan": None
        if done is None
        else {
            "feasible": bool(done.report.feasible),
            "violated": [c.name for c in done.report.violations],
            "knots_s": done.trajectory.knots.tolist(),
            "points": done.trajectory.points.tolist(),
            "points_layout": "points[p][k][j]: k-th time derivative (k = 0..4) of coordinate j at point p",
        },
    }
    (out / "replans.json").write_text(json.dumps(document, indent=1), encoding="utf-8")
    written.append("replans.json")
    if log is not None and final is not None:
        moved = [hooks.replanner.moves[i] for i in sorted(hooks.replanner.moves)]
        write_replanning_figure(
            out / "replanning.png", final.robot, final.trajectory, hooks.replanner.revisions, log, moved=moved
        )
        written.append("replanning.png")
    return timings


def passes(hooks, log) -> list[dict]:
    """For each move event: how close the simulated task point passes to the moved way point
    (:meth:`fpr.sim.replanning.InFlight.passes`); none without hooks or a log.
    """
    if hooks is None or log is None:
        return []
    return hooks.passes(log)


def summary(hooks, done, log=None) -> str:
    """Lines for stdout: each gust's holding verdict, each replan, how close the robot passed to moved way
    points, the executed plan.
    """
    if hooks is None:
        return ""
    held = [f"  gust {i}: {v.line()}" for i, v in sorted(getattr(hooks, "verdicts", {}).items())]
    moved = [
        f"  move event {p['event']}: the simulated {hooks.robot.kind.task_point_labels[0]} passes "
        f"{length(p['distance_m'])} from the moved way point {p['way_point']} at t = {p['time_s']:.3f} s"
        for p in passes(hooks, log)
    ]
    if hooks.replanner is None:
        lines = held + moved
        return "\n".join(["events in flight (no --replan: move events ignored):", *lines]) if lines else ""
    lines = [
        f"replanning in flight (deadline {hooks.replanner.options.deadline * 1e3:.0f} ms, "
        f"{hooks.replanner.options.timing} timing, latency model: {hooks.replanner.latency_model.source}):"
    ]
    for r in hooks.replans:
        lines.append(
            f"  t = {r.time:.3f} s, {r.trigger}: {r.why} (latency {r.latency_s * 1e3:.1f} ms, "
            f"solve {r.solve_wall_s * 1e3:.0f} ms wall, {plural(r.iterations, 'iteration')})"
        )
    late = [r for r in hooks.replans if r.why.startswith("not used: late")]
    if late:
        need = max(r.latency_s for r in late)
        lines.append(
            f"  {len(late)} of {plural(len(hooks.replans), 'replan')} {'was' if len(late) == 1 else 'were'} late: "
            f"they need up to {need * 1e3:.0f} ms on this machine ({hooks.replanner.options.timing} timing); "
            f"--replan-deadline {_rounded_up(1.2 * need):g} "
            "lets them in (documentation: guides/replanning, latency)"
        )
    if done is not None:
        state = (
            "holds every constraint"
            if done.report.feasible
            else "violates " + ", ".join(c.name for c in done.report.violations)
        )
        lines.append(f"  the executed plan (the plan in force at each instant) {state}")
    return "\n".join(lines + held + moved)


def _rounded_up(seconds: float) -> float:
    """``seconds`` rounded up to a deadline a person would type: 2 significant digits, at least 0.01 s."""
    step = 10.0 ** (np.floor(np.log10(max(seconds, 0.01))) - 1)
    return float(np.ceil(seconds / step - 1e-9) * step)


def problems(done) -> list[str]:
    """Why the run breaks a limit after replanning (exit 1): an executed plan that breaks a constraint."""
    if done is None or done.report.feasible:
        return []
    names = ", ".join(
        f"{c.name} (margin {c.margin:.4g} {c.unit} at t = {c.time:.3f} s)" for c in done.report.violations
    )
    return [f"the executed plan (after replanning) violates {names}"]
