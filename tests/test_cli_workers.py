"""``python -m fpr.campaign``'s worker processes: how many (bounded by the machine), and the watch that ends
them with the campaign (:mod:`fpr.cli.workers`). The processes themselves are tested in test_cli_signals.py.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from fpr.cli import workers


@pytest.fixture
def machine(monkeypatch):
    """A machine of 2 cores and 1 GB available, whatever runs the test."""
    monkeypatch.setattr(workers, "usable_cores", lambda: 2)
    monkeypatch.setattr(workers, "available_memory", lambda: 1_000_000_000)


def test_the_default_is_one_worker_per_core(machine):
    assert workers.bounded_workers(None, per_worker=100_000_000) == (2, None)


def test_more_workers_than_cores_are_capped_with_a_warning(machine):
    count, warning = workers.bounded_workers(1000, per_worker=100_000_000)
    assert count == 2
    assert warning.startswith("warning: --workers 1000:") and "2 usable cores" in warning
    assert "using 2 workers" in warning and "1 GB of memory available" in warning and "100 MB a worker" in warning


def test_the_memory_bounds_the_workers_too(machine):
    count, warning = workers.bounded_workers(2, per_worker=600_000_000)
    assert count == 1 and "using 1 worker " in warning
    assert workers.bounded_workers(1, per_worker=600_000_000) == (1, None)
    assert workers.bounded_workers(4, per_worker=10 ** 12)[0] == 1  # never 0


def test_the_machine_is_read_at_run_time():
    assert workers.usable_cores() >= 1
    own = workers.own_memory()
    assert own is None or 10_000_000 < own < 10 ** 12  # this test process: tens of MB or more
    free = workers.available_memory()
    assert free is None or free > 0


def test_a_worker_ends_when_its_parent_is_gone(tmp_path):
    """A grandchild watching its parent (the child) ends within a few watch intervals of the child's end."""
    code = ("import os, subprocess, sys, time\n"
            "child = subprocess.Popen([sys.executable, '-c', "
            "'from fpr.cli.workers import watch_parent; import time; watch_parent(); time.sleep(60)'])\n"
            f"open({str(tmp_path / 'pid')!r}, 'w').write(str(child.pid))\n"
            "time.sleep(1.0)\n"
            "os._exit(0)\n")  # the parent dies without a word to its child
    subprocess.run([sys.executable, "-c", code], timeout=60, check=True)
    pid = int((tmp_path / "pid").read_text())
    deadline = time.monotonic() + 10 * workers.WATCH_INTERVAL + 5
    while time.monotonic() < deadline and _alive(pid):
        time.sleep(0.05)
    assert not _alive(pid)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stream:
            return stream.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_a_worker_whose_campaign_died_before_it_started_ends_at_once():
    env = {**os.environ, workers.PARENT_VARIABLE: str(_a_finished_process())}
    proc = subprocess.run([sys.executable, "-c", "from fpr.cli.workers import watch_parent; watch_parent(); "
                                                 "print('still here')"], env=env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 1 and "still here" not in proc.stdout


def _a_finished_process() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid
