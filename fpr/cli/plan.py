"""``python -m fpr.plan``: plan a mission of the FPR or the prototype, and write what the drones must do.

With no argument it plans the built-in ``square`` mission with the 2-step optimisation (seed
3.2.4) and prints a table comparing the optimised motion with the stop-at-every-way-point one:
J_e, J_phi, peak rotor force and speed, least ground clearance, least singularity margin and
solve time, then the worst value of every constraint. Into ``--out`` (default
``fpr-out/<mission>``) it writes:

* ``mission.toml``: the mission as planned (command-line overrides included), re-usable with --mission;
* ``plan.json``: mission, robot parameters, summaries of both motions, solver stages, the
  points, durations and monomial coefficients of every segment;
* ``trajectory.csv``: one row per sample at ``--rate`` (columns and units in the documentation, guides/plan-command);
* ``reference.csv``: the same for the stop-at-every-way-point motion;
* ``manifest.json``: the command line, fpr's version, a hash of the inputs (the mission as planned and
  the options), the start time, the duration, the exit code and the wall-clock timings;
* PNG figures of the thesis' planning chapter (``fpr.views.figures``);
* with ``--simulate``: ``simulation.npz`` (the :class:`fpr.sim.closed_loop.SimulationLog`), ``simulation.json``
  (its summary and every planned constraint's closed-loop margin against the planning and the physical limit,
  :mod:`fpr.sim.margins`), ``sim_*``
  columns in ``trajectory.csv`` and the simulation figures; the summary adds tracking errors,
  out-of-plane motion, rotor speeds in the plant, allocation saturations and the real-time factor;
* with ``--simulate --replan``: ``replans.json`` and the executed plan in ``trajectory.csv``
  (:mod:`fpr.cli.replanning`); a mission's gusts push the simulated robot with or without ``--replan``;
* with ``--meshcat``: ``scene.html``, the 3D scene of :mod:`fpr.views.scene` (the robot following the plan;
  with ``--simulate``, the simulated robot and the plan as a ghost), a standalone page; ``--serve``
  also sends it to a live meshcat server, prints its URL and waits for Ctrl-C.

Every file goes into a temporary folder beside ``--out``, swapped in when complete with a
``manifest.json`` (command, fpr version, hash of the inputs, start time, duration, exit code, wall-clock
timings); a failed or interrupted run leaves the previous folder as it was (:mod:`fpr.cli.output`).

Exit codes (:mod:`fpr.cli.contract`): 0 every constraint holds; 1 the result breaks a limit (the planned
motion violates a constraint, or the simulation lost the robot or broke a physical limit; the files are still
written and the message names what broke); 2 bad input (mission file or option, unreachable way point, way
point on a singularity, a robot parameter out of its range, work over the size limits of :mod:`fpr.cli.checks`,
an ``--out`` that cannot be written); 3 internal error (a bug; ``--debug`` shows the traceback); 130
interrupted.
"""

from __future__ import annotations

import json
import signal
import sys
import time
from pathlib import Path

import numpy as np

from fpr.cli import checks, contract, replanning
from fpr.cli.interrupts import raise_if_interrupted
from fpr.cli.output import OutputError, OutputFolder, inputs_hash, manifest, write_deterministic_npz, write_manifest
from fpr.cli.plan_files import csv_columns, plan_document, split_timings, write_csv
from fpr.cli.plan_options import parser
from fpr.cli.text import plural
from fpr.model.errors import FprError, MissionError
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.margins import (
    broken_message,
    closed_loop_margins,
    eaten,
    margin_lines,
    margin_series,
    simulation_document,
    thrust_floor,
)
from fpr.sim.plant import PlantDivergedError
from fpr.tuning import tune_process
from fpr.views.figures import margins_figure, plan_figures, simulation_figures
from fpr.views.figures.all_figures import CROSSING_FIGURES
from fpr.views.scene import view
from planners.methods import CROSSING_METHODS, method_for
from planners.missions.mission import load_mission
from planners.optimize import PlanResult, plan

__all__ = ["comparison_table", "csv_columns", "main", "parser", "plan_document", "work", "write_csv"]


_OPTION_OF_FIELD = {"times": "--times", "via_points": "--via-points", "alpha": "--alpha"}


def _mission(args):
    """The mission as planned: the file (or built-in mission) with the options over its fields."""
    mission = load_mission(args.mission)
    changes = {}
    n_travel = len(mission.times)
    if args.times is not None:
        changes["times"] = args.times * n_travel if len(args.times) == 1 else args.times
    if args.via_points is not None:
        changes["via_points"] = args.via_points[0] if len(args.via_points) == 1 else args.via_points
    if args.alpha is not None:
        changes["alpha"] = args.alpha
    if args.robot_parameters:
        changes["robot_parameters"] = {**mission.robot_parameters, **dict(args.robot_parameters)}
    try:
        if changes:
            mission = mission.replace(**changes)
    except MissionError as error:  # an option's value: name the option, not the mission file's field
        option = _OPTION_OF_FIELD.get(error.field.split("[")[0])
        if option is None or getattr(args, option[2:].replace("-", "_")) is None:
            raise
        given = getattr(args, option[2:].replace("-", "_"))
        raise checks.CommandLineError(option, given, f"{error.field}: {error.reason}") from error
    if args.robot is not None and args.robot != mission.robot:
        raise FprError(f"--robot {args.robot}: mission {mission.name!r} is for the {mission.robot!r} robot; "
                       f"drop --robot or pick a mission for {args.robot!r}")
    return mission


# ------------------------------------------------------------------------------------------- files


_TABLE_ROWS = [("J (3.26)", "J", "", "{:.4f}"), ("J_e (energy index)", "J_e", "J", "{:.3f}"),
               ("J_phi (perturbation index)", "J_phi", "rad^2/s", "{:.4f}"),
               ("peak thrust", "peak_thrust_N", "N", "{:.3f}"),
               ("peak rotor force", "peak_rotor_force_N", "N", "{:.3f}"),
               ("peak rotor speed", "peak_rotor_speed_rad_s", "rad/s", "{:.1f}"),
               ("least rotor speed", "least_rotor_speed_rad_s", "rad/s", "{:.1f}"),
               ("peak |roll|", "peak_roll_rad", "rad", "{:.4f}"),
               ("least ground clearance", "least_ground_clearance_m", "m", "{:.4f}"),
               ("least singularity margin", "least_singularity_margin_rad", "rad", "{:.4f}"),
               ("solve time", "wall_time_s", "s", "{:.3f}"),
               ("every constraint holds", "feasible", "", "{}")]
# a singularity crossing: no singularity margin (it is 0 by design), the crossing instead
_CROSSING_ROWS = [("q2 sign changes", "crossings", "", "{}"),
                  ("criterion residual (4.7)", "criterion_residual_Nm", "N m", "{:.2e}"),
                  ("crossing time", "crossing_time_s", "s", "{:.3f}")]


def comparison_table(reference: PlanResult, result: PlanResult | None = None) -> str:
    """The table ``python -m fpr.plan`` prints: the reference motion (stop at way points; for a
    singularity crossing, its first guess) beside the optimised one, one row per quantity.
    """
    results = [reference] + ([result] if result is not None else [])
    summaries = [r.summary() for r in results]
    rows = list(_TABLE_ROWS)
    if all(r.crossing is not None for r in results):
        rows = [row for row in rows if row[1] != "least_singularity_margin_rad"]
        rows[-2:-2] = _CROSSING_ROWS
        for s in summaries:
            s.update({key: s["crossing"][key] for _, key, _, _ in _CROSSING_ROWS})
    names = [r.label for r in results]
    lines = [f"  {'':28s} {'unit':8s}" + "".join(f"{n:>24s}" for n in names)]
    for label, key, unit, fmt in rows:
        lines.append(f"  {label:28s} {unit:8s}" + "".join(f"{fmt.format(s[key]):>24s}" for s in summaries))
    return "\n".join(lines)


class _Progress:
    """Prints one line per solver stage, updated in place on a terminal."""

    def __init__(self, stream):
        self.stream = stream
        self.tty = stream.isatty()
        self.stage = None

    def __call__(self, stage, iteration, value, violation):
        raise_if_interrupted()
        end = "\r" if self.tty else "\n"
        if self.tty and self.stage is not None and stage != self.stage:
            self.stream.write("\n")
        if self.tty or iteration == 1 or iteration % 10 == 0:
            self.stream.write(f"  {stage}: iteration {iteration:3d}  J = {value:.5f}  violation = {violation:.2e}{end}")
            self.stream.flush()
        self.stage = stage

    def close(self):
        if self.tty and self.stage is not None:
            self.stream.write("\n")


def _figure_options(final) -> dict:
    """What the figures must know of the motion: a singularity crossing gets chapter 4's titles, no assembly-mode
    bounds it crosses, and its thrust floor.
    """
    crossing = final.crossing is not None
    return {"figure_numbers": CROSSING_FIGURES if crossing else None, "crossing": crossing,
            "min_thrust": thrust_floor(final.report)}


def _simulate(args, robot, final, out, sampled, written):
    """Run the closed-loop simulation and write its files.

    Returns:
        (log, lost, margins): the :class:`fpr.sim.closed_loop.SimulationLog` (None if the plant diverged before
        a log could be made), one line saying how the robot was lost or which physical limit it broke (None
        if neither), and the closed-loop margins of :mod:`fpr.sim.margins` (written to simulation.json).
    """
    settings = SimulationSettings(hold=args.hold, initial_error=dict(args.initial_error),
                                  model_mass_scale=args.model_mass_scale,
                                  rotor_constant_scale=args.rotor_constant_scale,
                                  measurement_noise=tuple(args.noise or (0.0, 0.0)),
                                  wind=tuple(args.wind or (0.0, 0.0, 0.0)), takeoff=args.takeoff)
    settings = replanning.with_observer(args, settings)  # --no-observer (fpr/cli/replanning.py)
    quiet = args.quiet

    def progress(t, total):
        if not quiet:
            print(f"  simulating: {t:6.1f} / {total:.1f} s", file=sys.stderr, flush=True)

    hooks = replanning.in_flight(args, final, settings)  # events and --replan (fpr/cli/replanning.py)
    try:
        log = simulate(final, settings, progress, hooks)
    except PlantDivergedError as error:
        return None, f"the simulation lost the robot: {contract.one_line(error)}", None
    failure = getattr(log, "failure", None)
    done = replanning.executed(final, hooks)
    sampled = sampled if done is None else done.sampled(args.rate)  # planned columns: the plan in force
    shown_log = None if args.no_plots else log  # replans.json, and replanning.png unless --no-plots
    log.replanning = (hooks, done, replanning.write(out, hooks, done, written, shown_log, final))
    # the same bytes from run to run: no wall time (it is in manifest.json), fixed zip timestamps
    write_deterministic_npz(out / "simulation.npz", log.save, replace={"wall_time": np.nan})
    flown = final if done is None else done  # margins against the executed plan when --replan changed it
    margins = closed_loop_margins(flown, log)
    (out / "simulation.json").write_text(json.dumps(simulation_document(log, margins), indent=1), encoding="utf-8")
    written.append("simulation.json")
    write_csv(out / "trajectory.csv", robot, sampled, log)
    written.append("simulation.npz")
    if not args.no_plots:
        try:
            options = _figure_options(final)
            options.pop("min_thrust")
            written += [f.name for f in simulation_figures(out, robot, log, sampled, **options)]
            written.append(margins_figure(out / "sim_margins.png", margin_series(flown, log)).name)
        except Exception as error:  # noqa: BLE001 - a plotting failure must not lose the results
            print(f"warning: simulation figures not written: {contract.one_line(error)}", file=sys.stderr)
    lost = f"the simulation lost the robot: {contract.one_line(failure)}" if failure else broken_message(margins)
    return log, lost, margins


def _simulation_table(log, robot) -> str:
    s = log.summary()
    ground = robot.kind.ground_height
    lines = ["closed-loop simulation (cascaded CTC, closed-chain plant):"]
    for name in log.chain:
        lines.append(f"  tracking error {name:5s}  rms {s['tracking_rms'][name]:.3e}  max {s['tracking_max'][name]:.3e}"
                     f"  final {s['final_error'][name]:+.3e}")
    for name, value in s["max_abs_out_of_plane"].items():
        lines.append(f"  largest |{name}| {value:.3e}")
    lines.append(f"  rotor speeds in the plant: {s['least_rotor_speed_rad_s']:.1f} .. "
                 f"{s['peak_rotor_speed_rad_s']:.1f} rad/s (limits 0 .. {s['rotor_speed_limit_rad_s']:.0f}; "
                 f"planning limit {s['planning_speed_limit_rad_s']:.0f})")
    lines.append(f"  allocation saturated on {s['saturated_ticks']} of {s['ticks']} control ticks")
    lines.append(f"  largest closure error {s['max_closure_error_m']:.2e} m; least height of a drone's centre "
                 f"of mass above the ground {s['least_drone_height_m'] - ground:.3f} m (ground at z = {ground:g} m)")
    lines.append(f"  {s['simulated_s']:.1f} s simulated in {s['wall_time_s']:.1f} s "
                 f"(real-time factor {s['real_time_factor']:.2f})")
    return "\n".join(lines)


def _scene(args, robot, final, log, out, written):
    """Write scene.html (and with --serve start the server); returns the live Visualizer or None."""
    try:
        scene = view(robot, final, log)
        scene.write(out / "scene.html")
        written.append("scene.html")
        return scene.serve() if args.serve else None
    except (ImportError, FprError, OSError) as error:  # the plan's files are written: keep them, say why
        print(f"warning: meshcat scene not {'served' if args.serve else 'written'}: {error}", file=sys.stderr)
        return None


def _wait_for_interrupt() -> None:
    """Sleep until Ctrl-C (or SIGTERM): then return, and meshcat stops its server at exit."""
    def stop(*_):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)


def _inputs(args):
    """The mission and its robot, every number checked and the size of the work estimated (exit 2 if not)."""
    try:
        checks.check_options(args)
        checks.apply_defaults(args)
        mission = _mission(args)
        robot = mission.load_robot()
        mission.positions(robot)  # every way point reachable and away from singularities
        method_for(mission, args.method)  # a method that can plan this mission
        replanning.check_options(args, mission, robot)
        checks.check_work(args, mission, robot, optimised=args.method != "none")
    except MissionError as error:  # a --set value is the option's fault, not the mission file's
        key = error.field.removeprefix("robot_parameters.")
        given = dict(args.robot_parameters)
        if error.field.startswith("robot_parameters.") and key in given:
            raise FprError(f"--set {key}={given[key]:g}: {error.reason.removeprefix('rejected by fpr.load: ')}") \
                from error
        raise
    except (ValueError, TypeError, OSError) as error:  # FprError subclasses included: the input's fault
        if isinstance(error, FprError):
            raise
        raise FprError(f"{type(error).__name__}: {error}") from error
    return mission, robot


def _hashed_options(args) -> dict:
    """The options that change the results (the mission's own are in its TOML text)."""
    skip = {"out", "quiet", "debug", "serve", "mission", "times", "via_points", "alpha", "robot_parameters"}
    return {k: v for k, v in sorted(vars(args).items()) if k not in skip}


def _work(args, mission, robot, tmp, say):
    """Plan (and simulate) into the folder ``tmp``; returns (exit code, outcome, timings, visualizer)."""
    progress = None if args.quiet else _Progress(sys.stderr)
    reference = plan(mission, "none", robot=robot)
    result = None
    if args.method != "none":
        extra = dict(curvature="composite", stop="kkt") if args.optimal else {}
        result = plan(mission, args.method, robot=robot, progress=progress, solver=args.solver,
                      polish=not args.no_polish, **extra)
        if progress is not None:
            progress.close()
    final = result or reference
    (tmp / "mission.toml").write_text(mission.to_toml(), encoding="utf-8")
    document = plan_document(mission, robot, final, reference)
    timings = split_timings(document)
    (tmp / "plan.json").write_text(json.dumps(document, indent=1), encoding="utf-8")
    sampled = final.sampled(args.rate)
    write_csv(tmp / "trajectory.csv", robot, sampled)
    written = ["mission.toml", "plan.json", "trajectory.csv"]
    reference_sampled = None
    if result is not None:
        reference_sampled = reference.sampled(args.rate)
        write_csv(tmp / "reference.csv", robot, reference_sampled)
        written.append("reference.csv")
    if not args.no_plots:
        try:
            figures = plan_figures(tmp, robot, sampled, reference_sampled, **_figure_options(final))
            written += [f.name for f in figures]
        except Exception as error:  # noqa: BLE001 - a plotting failure must not lose the computed plan
            print(f"warning: figures not written: {contract.one_line(error)}", file=sys.stderr)
    log, lost, margins = _simulate(args, robot, final, tmp, sampled, written) if args.simulate else (None,) * 3
    hooks, done, replan_timings = getattr(log, "replanning", (None, None, {}))
    if log is not None:
        timings["simulation"] = log.wall_time
        timings.update(replan_timings)
    shown = final if done is None else done  # after replanning, the ghost follows the plan in force
    visualizer = _scene(args, robot, shown, log, tmp, written) if args.meshcat or args.serve else None
    say(comparison_table(reference, result))
    say("constraints of the " + ("optimised" if result is not None else "stop-at-way-points") + " motion "
        "(dense grid, margin >= 0 holds):")
    for report in final.report.constraints.values():
        say("  " + report.describe())
    for stage in final.stages:
        kkt = "" if "KKT residual" in stage.message else f", KKT residual {stage.kkt:.2g}"
        say(f"  solver {stage.name}: {stage.message} ({plural(stage.iterations, 'iteration')}, "
            f"{stage.wall_time:.3f} s{kkt})")
    if log is not None:
        say(_simulation_table(log, robot))
    if margins is not None:
        say("\n".join(margin_lines(margins)))
    if hooks is not None and replanning.summary(hooks, done, log):
        say(replanning.summary(hooks, done, log))
    problems = []
    if not final.feasible:
        names = ", ".join(f"{c.name} (margin {c.margin:.4g} {c.unit} at t = {c.time:.3f} s)"
                          for c in final.report.violations)
        problems.append(f"the planned motion violates {names}; give more time (--times), more via points "
                        "(--via-points) or move the way points")
    if lost is not None:
        problems.append(lost)
    problems += replanning.problems(done)
    for problem in problems:
        print(f"error: {problem}", file=sys.stderr)
    outcome = "; ".join(problems) or "every constraint holds" + (", the robot was not lost" if args.simulate else "")
    if margins is not None and eaten(margins):  # reported, not a failure
        outcome += "; the closed loop ate into the design margin of " + ", ".join(m.name for m in eaten(margins))
    return (contract.LIMIT_BROKEN if problems else contract.OK), outcome, timings, visualizer


def _method_line(mission, method: str) -> str:
    """The method that plans ``mission`` when ``method`` is asked, as the summary line says it."""
    if mission.cross_singularity and method not in CROSSING_METHODS:
        crossing = CROSSING_METHODS[0]
        return f"{method} (the crossing's first guess)" if method == "none" else \
            f"{crossing} (a singularity-crossing mission is planned by the {crossing} method)"
    return method


def work(args, argv) -> int:
    """Plan (and simulate) as the options say and write the output folder; returns 0 or 1 (the result breaks
    a limit). Bad input raises :class:`fpr.model.errors.FprError` before any work (:func:`fpr.cli.contract.run`
    maps what it raises to the exit codes).
    """
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    started, start = time.time(), time.perf_counter()
    mission, robot = _inputs(args)
    safe_name = "".join(c if c.isalnum() or c in "-_." else "_" for c in mission.name).lstrip(".") or "mission"
    folder = OutputFolder(args.out or Path("fpr-out") / safe_name[:100])
    needed = checks.output_size(args, mission, robot)
    vias = sorted({int(n) for n in mission.via_points})
    say(f"mission {mission.name!r} ({mission.robot}): {plural(len(mission.times), 'travel')}, "
        f"{float(np.sum(mission.times)):g} s, via points per travel "
        f"{vias[0] if len(vias) == 1 else list(map(int, mission.via_points))}, alpha {mission.alpha:g}, "
        f"method {_method_line(mission, args.method)}")
    try:
        tmp = folder.open()
        folder.check_space(needed)
        code, outcome, timings, visualizer = _work(args, mission, robot, tmp, say)
        files = sorted(p.name for p in tmp.iterdir())
        command = parser().prog.split() + list(argv)
        write_manifest(tmp, manifest(command, inputs_hash(mission.to_toml(), _hashed_options(args)), started,
                                     time.perf_counter() - start, code, outcome, files, timings))
        folder.commit()
    except OSError as error:
        folder.discard()
        if error.errno in contract.NO_SPACE and not isinstance(error, OutputError):
            raise folder.no_space(error, needed) from error
        raise
    except BaseException:
        folder.discard()
        raise
    say(f"wrote {', '.join(files)} and manifest.json into {folder.path} ({time.perf_counter() - start:.1f} s)")
    if visualizer is not None:
        print(f"meshcat: open {visualizer.url()} (Ctrl-C to stop the server)", flush=True)
        _wait_for_interrupt()
    return code


def main(argv=None) -> int:
    """Command line entry point; returns the exit code (0, 1, 2, 3 or 130: see ``--help``)."""
    tune_process()  # one BLAS thread, freed memory kept in glibc's heap (fpr.tuning)
    return contract.command(parser(), argv, work)


if __name__ == "__main__":
    raise SystemExit(main())
