"""``python -m fpr.campaign``: a robustness campaign, many closed-loop flights of one plan under sampled
perturbations, run on Dask.

The mission is planned once; each run flies that plan through :func:`fpr.sim.closed_loop.simulate` with its own
draw of the varied quantities (``--vary NAME=DISTRIBUTION``, :mod:`fpr.robustness.spec`), on a local Dask
cluster (``--workers K`` processes, one thread each; default: one per usable core, at most as many as the cores
and the memory hold, :mod:`fpr.cli.workers`) or an existing one
(``--scheduler ADDRESS``). Into ``--out`` (default ``fpr-out/campaign-<mission>``) it writes, as runs finish,
one file per run (``runs/``), and at the end ``runs.parquet``, ``summary.json`` and the figures
(:mod:`fpr.robustness.store`). The same command again reuses every stored run and simulates only the missing
ones (after Ctrl-C, a lost worker, or with a larger ``--runs``).

Exit codes (:mod:`fpr.cli.contract`): 0 the campaign is complete; 1 complete, but a limit is broken: the plan
itself violates a constraint, or, with ``--min-success P``, the lower end of the success rate's 95 % Wilson
interval is below P (lost robots alone are results, not a broken limit); 2 bad input (a distribution, a
quantity, a campaign or mission file, an ``--out`` that holds something else); 3 internal error; 130
interrupted: the runs finished so far stay stored, the same command resumes; the worker processes end at
once, and with the campaign's process even when it is killed (:mod:`fpr.cli.workers`).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

from fpr import robots
from fpr.cli import checks, contract, interrupts, workers
from fpr.cli.campaign_options import EXIT_CODES, MAX_RUNS, parser
from fpr.cli.text import plural
from fpr.files import write_atomic
from fpr.model.errors import CampaignError, MissionError
from fpr.robustness.campaign_file import campaign_from_dict, campaign_to_toml
from fpr.robustness.runner import make_flight, mission_of, run_campaign
from fpr.robustness.spec import INITIAL_ERROR, SETTINGS, Campaign, components
from fpr.robustness.store import RunStore
from fpr.robustness.summary import event_summary, summarise, write_table
from fpr.sim.closed_loop import SimulationSettings
from fpr.tuning import tune_process
from fpr.views.figures.campaign import campaign_figures
from planners.missions.files import parse_toml, read_toml_text

__all__ = ["EXIT_CODES", "MAX_RUNS", "Progress", "main", "parser", "work"]


def _campaign_file(path) -> Campaign:
    """The campaign file, read as a mission file is (a size cap, UTF-8 with or without a byte-order mark, no
    pathological TOML: :mod:`planners.missions.files`), its fields as
    :func:`fpr.robustness.campaign_file.load_campaign` reads them.
    """
    try:
        document = parse_toml(read_toml_text(path, "campaign", "give the path of a .toml campaign file"), str(path))
    except MissionError as error:
        raise CampaignError(f"--campaign {path}", error.reason) from None
    return campaign_from_dict(document, Path(path))


def _campaign(args) -> Campaign:
    """The campaign: the file's fields, the options over them, fixed perturbations as constants."""
    campaign = _campaign_file(args.campaign) if args.campaign is not None else Campaign()
    changes = {k: getattr(args, k) for k in ("mission", "method", "runs", "seed", "hold", "tracking_tolerance",
                                             "events", "replan", "without_observer")
               if getattr(args, k) is not None}
    if args.robot_parameters:
        changes["robot_parameters"] = {**campaign.robot_parameters, **dict(args.robot_parameters)}
    if "runs" in changes and not 1 <= changes["runs"] <= MAX_RUNS:
        raise checks.CommandLineError("--runs", changes["runs"], f"give a number of runs in [1, {MAX_RUNS:,}]")
    if "seed" in changes and changes["seed"] < 0:
        raise checks.CommandLineError("--seed", changes["seed"], "give an integer >= 0")
    campaign = Campaign(**{**campaign.__dict__, **changes})
    fixed = [(name, value) for name, value in (("model_mass_scale", args.model_mass_scale),
                                               ("rotor_constant_scale", args.rotor_constant_scale),
                                               ("wind", args.wind), ("noise", args.noise)) if value is not None]
    fixed += [(INITIAL_ERROR + name, value) for name, value in args.initial_error]
    for name, value in fixed:  # constants (over the file's); --vary comes after: it wins
        campaign = campaign.with_vary(name, value)
    for name, text in args.vary:
        campaign = campaign.with_vary(name, text)
    return campaign


def _plan_options(campaign: Campaign, values: dict) -> argparse.Namespace:
    """The options ``python -m fpr.plan --simulate`` would get for these values (for :mod:`fpr.cli.checks`)."""
    wind = [values.get(c, 0.0) for c in components("wind")]
    noise = [values.get(c, 0.0) for c in components("noise")]
    return argparse.Namespace(rate=200.0, alpha=None, times=None, via_points=None, robot_parameters=[],
                              model_mass_scale=values.get("model_mass_scale", 1.0),
                              rotor_constant_scale=values.get("rotor_constant_scale", 1.0), wind=wind,
                              noise=noise, hold=campaign.hold, simulate=True,
                              initial_error=[(k[len(INITIAL_ERROR):], v) for k, v in values.items()
                                             if k.startswith(INITIAL_ERROR)])


def _check_ranges(campaign: Campaign, mission, robot) -> None:
    """Every value a distribution can give (its bounds, or its mean for an unbounded one) passes the checks of
    ``python -m fpr.plan --simulate`` (:mod:`fpr.cli.checks`) and of ``fpr.load`` (robot parameters); the
    simulated time is within the limit.
    """
    for name in campaign.columns:
        dist = campaign.vary[name]
        low, high = dist.support()
        for value in {v for v in (low, high, dist.typical()) if abs(v) != float("inf")}:
            try:
                if name in SETTINGS or name.startswith(INITIAL_ERROR):
                    checks.check_options(_plan_options(campaign, {name: value}))
                else:
                    robots.check_parameters({name: value}, {**mission.robot_parameters, name: value})
            except (checks.CommandLineError, ValueError) as error:
                raise CampaignError(f"--vary {name}={dist.text()}", f"it can give {value:g}: "
                                    f"{getattr(error, 'reason', error)}") from None
    checks.check_work(_plan_options(campaign, {}), mission, robot, optimised=campaign.method != "none")


class Progress:
    """The progress bar on stderr: runs done (reused), failures, rate, time left; redrawn in place on a
    terminal, a line every 10 s (and at the end) otherwise.
    """

    def __init__(self, total: int, stream=None, quiet: bool = False):
        self.total, self.stream, self.quiet = total, stream or sys.stderr, quiet
        self.tty = self.stream.isatty()
        self.start = self.reused = None
        self.last = 0.0

    def __call__(self, done: int, failures: int) -> None:
        """Show ``done`` runs of the total (the first call: those reused), ``failures`` among them."""
        now = time.perf_counter()
        if self.start is None:
            self.start, self.reused = now, done
        fresh = done - self.reused
        rate = fresh / (now - self.start) if fresh and now > self.start else 0.0
        left = f"{(self.total - done) / rate:.0f} s left" if rate else "time left: -"
        width = 24
        filled = int(width * done / self.total)
        line = (f"[{'#' * filled}{'.' * (width - filled)}] {done}/{self.total} runs ({self.reused} reused), "
                f"{failures} failed, {rate:.2f} runs/s, {left}")
        if self.quiet:
            return
        if self.tty:
            self.stream.write("\r" + line + ("\n" if done == self.total else ""))
        elif done == self.total or now - self.last >= 10.0 or fresh == 0:
            self.stream.write(line + "\n")
            self.last = now
        self.stream.flush()


MAX_SEED = 2 ** 63 - 1
"""Largest campaign seed (a TOML integer: the campaign file must read it back)."""


def _check_campaign(args, campaign: Campaign) -> None:
    """The campaign's numbers (from its file or the options) within their ranges (exit 2 if not)."""
    where = "--campaign " + str(args.campaign) + ": " if args.campaign is not None else ""
    if campaign.runs > MAX_RUNS:
        option = "--runs" if args.runs is not None else f"{where}field 'runs' ="
        raise checks.CommandLineError(option, campaign.runs, f"give a number of runs in [1, {MAX_RUNS:,}]")
    if campaign.seed > MAX_SEED:
        option = "--seed" if args.seed is not None else f"{where}field 'seed' ="
        raise checks.CommandLineError(option, campaign.seed, f"give an integer in [0, {MAX_SEED}]")
    tolerance = campaign.tracking_tolerance
    lost = SimulationSettings().max_tracking_error
    if tolerance is not None and tolerance > lost:
        option = ("--tracking-tolerance" if args.tracking_tolerance is not None
                  else f"{where}field 'tracking_tolerance' =")
        raise checks.CommandLineError(option, tolerance, f"give a tolerance in (0, {lost:g}] [m or rad]: past "
                                                         f"{lost:g} the simulation counts the robot lost anyway")
    if campaign.hold > checks.MAX_SIMULATED:
        option = "--hold" if args.hold is not None else f"{where}field 'hold' ="
        raise checks.CommandLineError(option, campaign.hold, f"give a time in [0, {checks.MAX_SIMULATED:g}] [s]")


def _client(args, say):
    """The Dask client: of the scheduler given, or of a local cluster of a bounded number of workers."""
    if args.scheduler:
        from distributed import Client

        try:
            return Client(args.scheduler, timeout="20s")
        except (OSError, TimeoutError) as error:
            raise CampaignError(f"--scheduler {args.scheduler}", f"cannot reach the scheduler ({error}): start "
                                "one (dask scheduler) or drop --scheduler for a local cluster") from None
    count, warning = workers.bounded_workers(args.workers)
    if warning is not None:
        print(warning, file=sys.stderr, flush=True)
    return workers.local_client(count)


def work(args, argv) -> int:
    """Run the campaign as the options say (resuming from ``--out``); returns 0 or 1 (a limit is broken).

    Bad input raises before the runs (:func:`fpr.cli.contract.run` maps it to exit 2); Ctrl-C or SIGTERM ends
    the worker processes at once and returns 130 (the runs finished so far stay stored).
    """
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, flush=True))
    if args.min_success is not None:
        checks._number("--min-success", args.min_success, low=0.0, high=1.0, meaning="a success rate")
    if args.workers is not None and args.workers < 1:
        raise checks.CommandLineError("--workers", args.workers, "give a number of worker processes >= 1")
    if args.runs is not None and not 1 <= args.runs <= MAX_RUNS:
        raise checks.CommandLineError("--runs", args.runs, f"give a number of runs in [1, {MAX_RUNS:,}]")
    if args.seed is not None and not 0 <= args.seed <= MAX_SEED:
        raise checks.CommandLineError("--seed", args.seed, f"give an integer in [0, {MAX_SEED}]")
    for option, value in (("--hold", args.hold), ("--tracking-tolerance", args.tracking_tolerance)):
        if value is not None:
            checks._number(option, value, low=0.0, low_open=option != "--hold", meaning="[s] or [m or rad]")
    campaign = _campaign(args)
    _check_campaign(args, campaign)
    mission = mission_of(campaign)
    robot = mission.load_robot()
    _check_ranges(campaign, mission, robot)
    safe_name = "".join(c if c.isalnum() or c in "-_." else "_" for c in mission.name).lstrip(".") or "mission"
    out = args.out or Path("fpr-out") / f"campaign-{safe_name[:100]}"
    key = campaign.key(mission.to_toml())
    say(f"campaign: mission {mission.name!r} ({mission.robot}), {plural(campaign.runs, 'run')}, seed {campaign.seed}, "
        f"varied: {', '.join(f'{k}={d.text()}' for k, d in sorted(campaign.vary.items())) or 'nothing'}")
    flight, result = make_flight(campaign, mission)
    store = RunStore(out, key, {"campaign": campaign_to_toml(campaign, "mission.toml"),
                                "mission": mission.name, "command": ["python", "-m", "fpr.campaign", *argv]})
    write_atomic(out / "mission.toml", mission.to_toml())
    write_atomic(out / "campaign.toml", campaign_to_toml(campaign, "mission.toml"))
    say(f"plan ({campaign.method}): {'every constraint holds' if result.feasible else 'VIOLATES a constraint'}")
    progress = Progress(campaign.runs, quiet=args.quiet)
    client = None
    try:
        client = _client(args, say)
        done = run_campaign(campaign, flight, store, client, progress)
    except KeyboardInterrupt:
        interrupts.ending()  # a second Ctrl-C ends the process at once
        logging.disable(logging.CRITICAL)  # the cluster's complaints about its killed workers are not news
        with workers.quiet_stderr():  # the processes the cluster still starts cannot print over the line
            workers.end_children()  # the worker processes end now, not after a graceful close
        stored = len(store.load(campaign.runs))
        print(f"interrupted: {stored} of {campaign.runs} runs stored in {out}; the same command resumes",
              file=sys.stderr, flush=True)
        return contract.INTERRUPTED
    if client is not None:
        _close(client)
    varied = list(campaign.columns)
    columns = ["index", *varied, *flight.columns]
    write_table(out / "runs.parquet", done.rows, columns)
    summary = summarise(done.rows, varied, list(flight.columns))
    summary.update({"reused": done.reused, "computed": done.computed, "workers": done.workers,
                    "wall_time_s": round(done.wall_time, 3),
                    "runs_per_second": done.computed / done.wall_time if done.computed else None,
                    "plan_feasible": bool(result.feasible)})
    if campaign.events is not None:
        summary["events"] = event_summary(done.rows, campaign.events, campaign.without_observer)
    write_atomic(out / "summary.json", json.dumps(summary, indent=1) + "\n")
    if not args.no_plots:
        try:
            campaign_figures(out, done.rows, varied, list(flight.chain), robot.rotor_constants.max_speed)
        except Exception as error:  # noqa: BLE001 - a plotting failure must not lose the table
            print(f"warning: figures not written: {contract.one_line(error)}", file=sys.stderr)
    low, high = summary["success_rate_wilson95"]
    say(f"{summary['successes']} of {plural(summary['runs'], 'run')} succeeded ({summary['success_rate']:.1%}, 95 % "
        f"Wilson interval {low:.1%} .. {high:.1%}); lost {summary['lost']}, errors {summary['errors']}; "
        f"{done.reused} reused, {done.computed} simulated in {done.wall_time:.1f} s on {done.workers} "
        f"worker{'s' if done.workers != 1 else ''}")
    for kind, count in summary["lost_by_kind"].items():
        say(f"  lost: {kind}: {count}")
    if campaign.events is not None:
        for line in event_lines(summary["events"]):
            say(line)
    say(f"wrote runs.parquet, summary.json{'' if args.no_plots else ', figures'} into {out}")
    problems = []
    if not result.feasible:
        problems.append("the plan violates a constraint (every run flew it)")
    if args.min_success is not None and low < args.min_success:
        problems.append(f"the success rate's 95 % lower bound {low:.3f} is below --min-success {args.min_success:g}")
    for problem in problems:
        print(f"error: {problem}", file=sys.stderr)
    return contract.LIMIT_BROKEN if problems else contract.OK


def event_lines(events: dict) -> list[str]:
    """The event family's lines (:func:`fpr.robustness.summary.event_summary`)."""
    def rate(name, r):
        low, high = r["wilson95"]
        return (f"  {name}: {r['successes']} of {plural(r['runs'], 'run')} succeeded ({r['success_rate']:.1%}, "
                f"95 % Wilson interval {low:.1%} .. {high:.1%})")

    lines = [f"{events['family']} events:"]
    if "not_holdable" in events:
        lines.append(f"  {plural(len(events['not_holdable']), 'gust')} cannot be held even as a steady force within "
                     "the rotor limits (counted apart)"
                     + "".join(f"; run {g['index']}: {g['force_n']:.2g} N on {g['body']}"
                               for g in events["not_holdable"]))
    lines.append(rate("with the observer" if "without_observer" in events else "runs", events["with_observer"]))
    if "without_observer" in events:
        lines.append(rate("without the observer (same events)", events["without_observer"]))
    for miss in events["misses"]:
        lines.append(f"  miss, run {miss['index']}: {miss['why']}")
    for key, name in (("replan_wall_s", "wall latency"), ("replan_cpu_s", "CPU time")):
        got = events.get(key, {})
        if got.get("count"):
            lines.append(f"  replan {name} over {plural(got['count'], 'replan')}: median "
                         f"{got['median'] * 1e3:.1f} ms, p95 {got['p95'] * 1e3:.1f} ms, max {got['max'] * 1e3:.1f} ms")
    return lines


def _close(client) -> None:
    """Close the client (and its local cluster); never raises."""
    try:
        cluster = client.cluster
        client.close()
        if cluster is not None:
            cluster.close()
    except Exception:  # noqa: BLE001 - closing is best effort at the end
        pass


def main(argv=None) -> int:
    """Command line entry point; returns the exit code (0, 1, 2, 3 or 130: see ``--help``)."""
    tune_process()  # one BLAS thread, freed memory kept in glibc's heap (fpr.tuning)
    return contract.command(parser(), argv, work)


if __name__ == "__main__":
    raise SystemExit(main())
