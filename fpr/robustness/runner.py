"""The runs of a campaign on Dask: a local cluster of worker processes, or an existing cluster.

:func:`make_flight` plans the mission once; :func:`run_campaign` ships that plan to every worker once
(``Client.scatter(..., broadcast=True)``), submits one task per missing run (:func:`fpr.robustness.outcomes.fly`,
its values drawn from the campaign's seed and the run's index) and stores each row as its task finishes
(:class:`fpr.robustness.store.RunStore`). The rows depend only on the campaign and their index: the same
table comes out of 1 worker or 64, in one go or resumed.

Reliability is Dask's: a worker process that dies loses only the tasks it held, which the scheduler gives
to the other workers (a local cluster's nanny also restarts the worker). A run that kills workers again and
again (Dask's ``distributed.scheduler.allowed-failures``, 3 by default) ends as a row with the error
``KilledWorker``; such a row is not stored, so the next invocation tries it again.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field

from fpr import extras
from fpr.model import description
from fpr.model.errors import CampaignError
from fpr.robustness.outcomes import EventSetup, Flight, error_row, fly
from fpr.robustness.spec import INITIAL_ERROR, SETTINGS, Campaign
from fpr.robustness.store import RunStore
from fpr.tuning import tune_process
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.replanning.latency import machine_latency
from planners.replanning.replanner import measure_latency

logger = logging.getLogger(__name__)


def mission_of(campaign: Campaign):
    """The campaign's mission, with its fixed robot parameters (:class:`planners.missions.mission.Mission`)."""
    mission = load_mission(campaign.mission)
    if campaign.robot_parameters:
        mission = mission.replace(robot_parameters={**mission.robot_parameters, **campaign.robot_parameters})
    return mission


def check_quantities(campaign: Campaign, robot) -> None:
    """Every varied quantity is one the runs know: a setting, ``initial_error.<coordinate>`` of the robot, or a
    xacro argument of its description.

    Raises:
        CampaignError: the first unknown name, with the names that are known.
    """
    parameters = set(description.xacro_arguments(robot.kind.xacro))
    for name in campaign.columns:
        if name in SETTINGS or name in parameters:
            continue
        if name.startswith(INITIAL_ERROR):
            coordinate = name[len(INITIAL_ERROR):]
            if coordinate not in robot.index:
                raise CampaignError(name, f"unknown coordinate {coordinate!r} of the {robot.name} robot: use one "
                                          f"of {', '.join(robot.index)}")
            continue
        raise CampaignError(name, f"not a quantity a run can vary: use wind, noise, {', '.join(SETTINGS)}, "
                                  f"{INITIAL_ERROR}<coordinate> or a robot parameter ({', '.join(sorted(parameters))})")


def make_flight(campaign: Campaign, mission=None, progress=None, latency=None):
    """Plan the campaign's mission once.

    With an event family, the flight carries the mission, the plan's constraints (the closed loop's physical
    limits) and the :class:`fpr.robustness.outcomes.EventSetup`; the replanner's latency model is resolved here,
    once (``latency``, or this machine's calibration: :func:`planners.replanning.latency.machine_latency`), so
    that every worker decides alike; the first run's event is drawn here, to refuse a family that cannot give
    one before any run.

    Returns:
        (flight, result): the :class:`fpr.robustness.outcomes.Flight` the workers get and the
        :class:`planners.optimize.PlanResult` (for its feasibility and report).

    Raises:
        fpr.extras.MissingExtraError: the campaign extra (Dask, pyarrow) is not installed: checked before the
            plan's work, since the runs need it.
    """
    extras.require("campaign")
    mission = mission or mission_of(campaign)
    robot = mission.load_robot()
    check_quantities(campaign, robot)
    result = plan(mission, campaign.method, robot=robot, progress=progress)
    setup = None
    if campaign.events is not None:
        if campaign.replan and latency is None:
            latency = machine_latency(robot, measure_latency)
        setup = EventSetup(campaign.events, campaign.event_family(), campaign.seed, campaign.replan, latency,
                           campaign.without_observer, campaign.pass_tolerance, campaign.max_saturation)
        setup.event(mission, robot, 0)
    flight = Flight(robot.name, tuple(sorted(mission.robot_parameters.items())), tuple(robot.layout.chain),
                    result.trajectory, float(campaign.hold), campaign.tracking_tolerance,
                    mission if setup is not None else None,
                    result.report.constraints if setup is not None else None, setup)
    return flight, result


@dataclass
class CampaignRun:
    """What :func:`run_campaign` did.

    Attributes:
        rows: every run's row, by index (0 .. runs - 1).
        reused: runs found in the folder (not simulated again).
        computed: runs simulated now.
        wall_time: time spent on the runs (cluster start included) [s].
        workers: number of Dask workers when the runs started.
    """

    rows: list = field(default_factory=list)
    reused: int = 0
    computed: int = 0
    wall_time: float = 0.0
    workers: int = 0


def local_client(workers: int | None = None):
    """A Dask client of a new local cluster: ``workers`` processes (default: the number of cores), one thread
    each, its dashboard on a free port; closing the client closes the cluster. (Worker processes are
    spawned: in a script, call it under ``if __name__ == "__main__":``.) Each worker process calls
    :func:`fpr.tune_process` before its first run; it leaves alone what Dask's nanny already chose for its
    workers (by default one BLAS thread and ``MALLOC_TRIM_THRESHOLD_``, in ``distributed.nanny.pre-spawn-environ``).

    Raises:
        fpr.extras.MissingExtraError: the campaign extra is not installed.
    """
    extras.require("campaign")
    from distributed import Client

    n = int(workers or os.cpu_count() or 1)
    client = Client(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                    silence_logs=logging.ERROR)
    client.register_plugin(_tuned_worker())
    return client


def _tuned_worker():
    """A Dask worker plugin that makes :func:`fpr.tune_process` in each worker process, also in one the nanny
    restarts (a plugin's ``setup`` runs in every worker, present or future).
    """
    from distributed.diagnostics.plugin import WorkerPlugin

    class TunedWorker(WorkerPlugin):
        name = "fpr-tune-process"

        def setup(self, worker) -> None:
            tune_process()

    return TunedWorker()


def open_store(folder, campaign: Campaign, description: dict | None = None) -> RunStore:
    """The campaign's folder (:class:`fpr.robustness.store.RunStore`), keyed by the campaign and its mission."""
    return RunStore(folder, campaign.key(mission_of(campaign).to_toml()), description or {})


def run_campaign(campaign: Campaign, flight: Flight, store: RunStore, client, progress=None) -> CampaignRun:
    """Simulate the runs of ``campaign`` that ``store`` does not hold, on the Dask ``client``.

    Args:
        campaign: the campaign (its runs, seed and distributions).
        flight: the plan (:func:`make_flight`).
        store: the campaign's folder; each finished row is stored at once.
        client: a ``distributed.Client`` (of a local or remote cluster).
        progress: called as ``progress(done, failures)`` after each run (``done`` counts the reused ones),
            and once with (reused, failures among them) before the first.

    Returns:
        the :class:`CampaignRun`.

    A ``KeyboardInterrupt`` cancels the tasks still pending and propagates: what finished is stored.
    """
    extras.require("campaign")
    from distributed import as_completed

    start = time.perf_counter()
    stored = store.load(campaign.runs)
    rows = dict(stored)
    failures = sum(not r["success"] for r in rows.values())
    if progress is not None:
        progress(len(rows), failures)
    missing = [i for i in range(campaign.runs) if i not in rows]
    workers = len(client.scheduler_info(n_workers=-1)["workers"]) if missing else 0
    futures = []
    if missing:
        shipped = client.scatter(flight, broadcast=True)
        futures = [client.submit(fly, shipped, i, campaign.values(i), campaign.noise_seed(i), pure=False,
                                 key=f"fpr-run-{store.key[:16]}-{i}-{os.getpid()}-{time.monotonic_ns()}")
                   for i in missing]
    index_of = {f.key: i for f, i in zip(futures, missing, strict=True)}
    try:
        for future in as_completed(futures):
            i = index_of[future.key]
            if future.status == "finished":
                row = future.result()
                store.put(row)
            else:  # the engine gave up on it (KilledWorker, cancelled): a row now, tried again next time
                error = future.exception()
                row = {"index": i, **campaign.values(i), **error_row(flight, error)}
                logger.warning("run %d: %s", i, row["error"])
            rows[i] = row
            failures += not row["success"]
            if progress is not None:
                progress(len(rows), failures)
    except BaseException:
        client.cancel(futures)
        raise
    return CampaignRun([rows[i] for i in range(campaign.runs)], len(stored), len(missing),
                       time.perf_counter() - start, workers)
