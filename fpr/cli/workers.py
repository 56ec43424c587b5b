"""The worker processes of ``python -m fpr.campaign``'s local Dask cluster: how many, and that none outlives
the campaign.

* How many (:func:`bounded_workers`): at most one per usable core (the runs are single-threaded simulations:
  more processes than cores only share them) and at most as many as the available memory holds, a worker
  counting as much memory as the campaign's own process once it has planned (measured at run time: a
  worker imports the same modules and holds the same plan). A larger ``--workers`` is capped, with a
  warning that says why.
* None outlives the campaign: every worker process watches its parent (:func:`watch_parent`, started as
  early as the process runs fpr code: when ``python -m fpr.campaign`` is re-imported by Python's ``spawn``,
  and again by the cluster's preload, :func:`dask_setup`) and ends itself within :data:`WATCH_INTERVAL` when
  the campaign's process is gone, even if it was killed with SIGKILL. A campaign interrupted by Ctrl-C or
  SIGTERM ends its workers itself at once (:func:`end_children`).

A watch thread is used rather than Linux's parent-death signal (``prctl(PR_SET_PDEATHSIG)``): that signal
follows the *thread* that started the process, and Dask starts worker processes from threads of its own; the
watch follows the process, on every system.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time

PARENT_VARIABLE = "FPR_CAMPAIGN_PID"
"""Environment variable through which the campaign tells its worker processes its process id."""
WATCH_INTERVAL = 0.2
"""How often a worker process looks whether the campaign's process is still there [s]."""

_watching = False


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def available_memory() -> int | None:
    """The memory the system can give without swapping (``MemAvailable`` of ``/proc/meminfo``) [bytes], or
    None where unknown.
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as stream:
            for line in stream:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def own_memory() -> int | None:
    """The resident memory of this process [bytes], or None where unknown."""
    try:
        with open("/proc/self/statm", encoding="ascii") as stream:
            return int(stream.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return int(peak) * (1 if sys.platform == "darwin" else 1024)
    except (ImportError, OSError, ValueError):
        return None


def bounded_workers(requested: int | None, per_worker: int | None = None) -> tuple[int, str | None]:
    """The number of worker processes of a local cluster, and the warning to print when it caps ``requested``.

    Args:
        requested: ``--workers`` (None: the default, one per usable core).
        per_worker: the memory a worker needs [bytes] (default: :func:`own_memory`).

    Returns:
        (workers, warning or None).
    """
    cores = usable_cores()
    per_worker = own_memory() if per_worker is None else per_worker
    free = available_memory()
    by_memory = max(1, int(free // per_worker)) if free and per_worker else None
    bound = min(cores, by_memory) if by_memory is not None else cores
    wanted = cores if requested is None else int(requested)
    if wanted <= bound:
        return wanted, None
    memory = (f" and {free / 1e9:.3g} GB of memory available, about {per_worker / 1e6:.0f} MB a worker"
              if by_memory is not None else "")
    why = "more would only share the cores" + (" and the memory" if by_memory is not None else "")
    given = "" if requested is None else f"--workers {requested}: "
    return bound, (f"warning: {given}this machine has {cores} usable core{'s' if cores != 1 else ''}{memory}; "
                   f"using {bound} worker{'s' if bound != 1 else ''} ({why})")


def _exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: it exists
        return True
    return True


def watch_parent() -> None:
    """End this process (``os._exit``) as soon as its parent process is gone (a daemon thread; once).

    When :data:`PARENT_VARIABLE` names a campaign's process that is already gone (it was killed while this
    process started), this process ends at once.
    """
    global _watching
    if _watching:
        return
    parent = os.getppid()
    campaign = os.environ.get(PARENT_VARIABLE, "")
    if campaign.isdigit() and int(campaign) != parent and not _exists(int(campaign)):
        os._exit(1)
    _watching = True

    def watch():
        while os.getppid() == parent:
            time.sleep(WATCH_INTERVAL)
        os._exit(1)

    threading.Thread(target=watch, name="fpr: end with the campaign", daemon=True).start()


def dask_setup(worker=None) -> None:
    """Dask's preload hook, run in each worker process of the local cluster (:func:`local_client`)."""
    watch_parent()


def local_client(workers: int):
    """A Dask client of a new local cluster of ``workers`` processes (one thread each), each watching this
    process (:func:`watch_parent`); its dashboard on a free port; closing the client closes the cluster.
    """
    from distributed import Client

    _quiet_resource_tracker()
    previous = os.environ.get(PARENT_VARIABLE)
    os.environ[PARENT_VARIABLE] = str(os.getpid())  # inherited by the worker processes as they are spawned
    try:
        return Client(n_workers=int(workers), threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR, preload=[__name__])
    finally:
        if previous is None:
            os.environ.pop(PARENT_VARIABLE, None)
        else:
            os.environ[PARENT_VARIABLE] = previous


def _quiet_resource_tracker() -> None:
    """Start Python's multiprocessing resource tracker (the process that removes the semaphores of a process
    that ended without removing them) with its stderr on the null device.

    After Ctrl-C the campaign ends at once (:func:`fpr.cli.launch.finish`) and the tracker removes the worker
    queues' semaphores itself; it would print a warning and a traceback per semaphore over the campaign's one
    line.
    """
    try:
        from multiprocessing import resource_tracker
    except ImportError:  # pragma: no cover - every CPython has it
        return
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        resource_tracker.ensure_running()
    except OSError:
        pass
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def children() -> list[int]:
    """The process ids of every descendant of this process but the resource tracker (which cleans up after it)."""
    try:
        import psutil

        found = []
        for child in psutil.Process().children(recursive=True):
            try:
                if "resource_tracker" not in " ".join(child.cmdline()):
                    found.append(child.pid)
            except psutil.Error:
                continue
        return found
    except (ImportError, OSError):
        return []


def end_children() -> None:
    """Kill (SIGKILL) every descendant of this process (the worker processes): the campaign is ending after
    Ctrl-C or SIGTERM.

    Each is stopped (SIGSTOP) first, and the descendants listed again until no new one appears, then all are killed:
    a worker process whose parent (a nanny) were killed first would be left half-started, reading its start-up data
    from a closed pipe, and would print Python's traceback of that over the campaign's one line.
    """
    stopped: list[int] = []
    for _ in range(100):  # a process can start another only while it runs: this ends once all are stopped
        found = [pid for pid in children() if pid not in stopped]
        if not found:
            break
        for pid in found:
            try:
                os.kill(pid, signal.SIGSTOP)
            except OSError:
                pass
            stopped.append(pid)
    for pid in stopped:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


@contextlib.contextmanager
def quiet_stderr():
    """Within the block, this process's standard error (file descriptor 2), which every process it starts inherits,
    is the null device: a worker process the cluster was still starting while the campaign ends cannot print over
    the campaign's one line. The descriptor is restored after the block (``sys.stderr`` itself is left alone).
    """
    try:
        sys.stderr.flush()
    except (OSError, ValueError, AttributeError):
        pass
    try:
        saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    except OSError:
        yield
        return
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)
