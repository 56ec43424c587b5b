"""Ctrl-C and SIGTERM from the first instruction of every command, and no process left behind by a campaign.

These run the real commands in subprocesses (the exit code of the interpreter and the signals matter):

* ``--help`` imports neither the planner nor the simulator (``python -X importtime`` lists every import);
* from the moment a command's handlers are installed (read in ``/proc/<pid>/status``: SIGTERM caught), a
  SIGINT or SIGTERM at any later moment (while numpy, Pinocchio and the planner import, then during the
  work) ends it with exit 130 and one line on stderr;
* a campaign interrupted while its local Dask cluster starts, or while its runs go, ends at once with one
  line, and none of its processes is left; killed with SIGKILL, its worker processes end by themselves.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

psutil = pytest.importorskip("psutil")

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc/<pid>/status")


def _caught(pid: int) -> int:
    """The bit mask of the signals the process has handlers for (0 when it is gone)."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as stream:
            for line in stream:
                if line.startswith("SigCgt:"):
                    return int(line.split()[1], 16)
    except OSError:
        pass
    return 0


def _start(module: str, *argv, **kwargs) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", module, *argv], cwd=kwargs.pop("cwd", ROOT),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, **kwargs)


def _wait_for_handlers(process: subprocess.Popen, timeout: float = 60.0) -> float:
    """Wait until the process handles SIGTERM (its launch has run); returns how long that took [s]."""
    start = time.monotonic()
    while not _caught(process.pid) & (1 << (signal.SIGTERM - 1)):
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() - start < timeout
        time.sleep(0.002)
    return time.monotonic() - start


def _one_interrupted_line(process: subprocess.Popen, timeout: float = 60.0) -> str:
    _, err = process.communicate(timeout=timeout)
    # the work's indented progress lines (a planner's iterations) may come before it, on a fast machine
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("  ")]
    assert process.returncode == 130, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("interrupted"), err
    return lines[0]


def _modules_after_help(tmp_path, module: str) -> set[str]:
    """``python -m <module> --help`` with a hook that writes ``sys.modules`` at exit."""
    listing = tmp_path / f"{module}.modules"
    code = ("import atexit, runpy, sys\n"
            f"atexit.register(lambda: open({str(listing)!r}, 'w').write('\\n'.join(sorted(sys.modules))))\n"
            f"sys.argv = [{module!r}, '--help']\n"
            f"runpy.run_module({module!r}, run_name='__main__', alter_sys=True)\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "exit codes:" in proc.stdout, proc.stderr
    return set(listing.read_text().split())


def test_help_imports_neither_the_planner_nor_the_simulator(tmp_path):
    modules = _modules_after_help(tmp_path, "fpr.plan")
    assert "fpr.cli.plan_options" in modules and "fpr.cli.launch" in modules
    for heavy in ("planners.optimize", "fpr.sim.closed_loop", "pinocchio", "fpr.robots", "matplotlib"):
        assert heavy not in modules, heavy
    modules = _modules_after_help(tmp_path, "fpr.campaign")
    assert "fpr.cli.campaign_options" in modules
    assert not {"distributed", "pinocchio", "planners.optimize", "fpr.sim.closed_loop"} & modules


@pytest.mark.parametrize("signum, delay", [(signal.SIGINT, 0.0), (signal.SIGINT, 0.05), (signal.SIGINT, 0.3),
                                           (signal.SIGINT, 1.0), (signal.SIGTERM, 0.0), (signal.SIGTERM, 0.5)],
                         ids=["ctrl-c-at-once", "ctrl-c-50ms", "ctrl-c-300ms", "ctrl-c-1s", "sigterm-at-once",
                              "sigterm-500ms"])
def test_plan_interrupted_from_its_first_instruction(tmp_path, signum, delay):
    # a mission that plans for seconds after the imports: the last delays reach the work, not its end
    process = _start("fpr.plan", "--mission", "cross-singularity", "--no-plots", "--out", str(tmp_path / "out"))
    _wait_for_handlers(process)
    time.sleep(delay)
    process.send_signal(signum)
    _one_interrupted_line(process)
    assert not (tmp_path / "out").exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("module, argv", [("fpr.studies", ["--quick", "--quiet", "--out", "out"]),
                                          ("fpr.bench", ["--quick", "--json"]),
                                          ("fpr.campaign", ["--runs", "2", "--quiet", "--no-plots", "--out", "out"])],
                         ids=["studies", "bench", "campaign"])
def test_every_command_handles_ctrl_c_while_it_imports(tmp_path, module, argv):
    process = _start(module, *argv, cwd=tmp_path)
    _wait_for_handlers(process)
    time.sleep(0.2)
    process.send_signal(signal.SIGINT)
    _one_interrupted_line(process)


# ------------------------------------------------------------------------------------ campaign processes
def _descendants(pid: int) -> set[int]:
    try:
        return {child.pid for child in psutil.Process(pid).children(recursive=True)}
    except psutil.Error:
        return set()


def _alive(pids) -> list[int]:
    left = []
    for pid in pids:
        try:
            if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                left.append(pid)
        except psutil.Error:
            pass
    return left


def _campaign(tmp_path, runs: int = 200) -> subprocess.Popen:
    return _start("fpr.campaign", "--mission", "study", "--method", "none", "--runs", str(runs), "--hold", "0.2",
                  "--workers", "2", "--no-plots", "--quiet", "--out", str(tmp_path / "c"), cwd=tmp_path)


def _workers_of(process, seen: set, until, timeout: float = 240.0) -> None:
    """Collect the campaign's descendants until ``until()`` holds."""
    start = time.monotonic()
    while not until():
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() - start < timeout
        seen |= _descendants(process.pid)
        time.sleep(0.02)
    seen |= _descendants(process.pid)


def _none_left(seen, within: float = 10.0) -> None:
    deadline = time.monotonic() + within
    while _alive(seen) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = _alive(seen)
    for pid in left:  # do not leave them to the next tests
        os.kill(pid, signal.SIGKILL)
    assert not left, [" ".join(psutil.Process(p).cmdline())[:120] for p in left if psutil.pid_exists(p)]


def _runs_stored(tmp_path, count):
    folder = tmp_path / "c" / "runs"
    return lambda: folder.is_dir() and len(list(folder.glob("*.json"))) >= count


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["sigterm", "ctrl-c"])
def test_a_campaign_interrupted_while_its_cluster_starts_ends_at_once(tmp_path, signum):
    process, seen = _campaign(tmp_path), set()
    _workers_of(process, seen, lambda: len(_descendants(process.pid)) >= 2)  # the tracker and a first worker
    process.send_signal(signum)
    start = time.monotonic()
    line = _one_interrupted_line(process)
    assert time.monotonic() - start < 5.0 and "the same command resumes" in line
    _none_left(seen)


def test_a_campaign_interrupted_during_its_runs_ends_at_once(tmp_path):
    process, seen = _campaign(tmp_path), set()
    _workers_of(process, seen, _runs_stored(tmp_path, 2))
    process.send_signal(signal.SIGTERM)
    start = time.monotonic()
    line = _one_interrupted_line(process)
    assert time.monotonic() - start < 5.0 and "runs stored" in line
    _none_left(seen)


@pytest.mark.parametrize("moment", ["cluster-start", "runs"])
def test_a_killed_campaign_leaves_no_process_behind(tmp_path, moment):
    process, seen = _campaign(tmp_path), set()
    until = (lambda: len(_descendants(process.pid)) >= 2) if moment == "cluster-start" else _runs_stored(tmp_path, 2)
    _workers_of(process, seen, until)
    process.kill()  # SIGKILL: the campaign runs no code of its own
    process.communicate(timeout=30)
    _none_left(seen)


def test_an_interruption_a_callback_swallowed_is_raised_again():
    """A signal whose KeyboardInterrupt lands in a weakref callback (as in the import system's module-lock
    callbacks while modules load): Python drops it, the command's next check raises it again, and no traceback
    is printed.
    """
    code = """
import os, signal, sys, weakref
from fpr.cli import interrupts
interrupts.handle_signals()
class Thing:
    pass
def callback(_):
    os.kill(os.getpid(), signal.SIGINT)
    for _ in range(1000):  # the handler runs here, inside the callback
        pass
thing = Thing()
ref = weakref.ref(thing, callback)
del thing
print("ran on", flush=True)
try:
    interrupts.raise_if_interrupted()
except KeyboardInterrupt:
    sys.exit(130)
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert (result.returncode, result.stdout, result.stderr) == (130, "ran on\n", "")


def test_an_interruption_that_comes_out_as_another_error_ends_as_an_interruption():
    """A KeyboardInterrupt that C code turns into another error (numpy's C-extension import makes it an
    ImportError when the signal lands while it imports datetime): exit 130 and the interruption's one line.
    """
    code = """
import os, signal, sys
from fpr.cli import contract, interrupts
interrupts.handle_signals()
def work():
    try:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):
            pass
    except KeyboardInterrupt:
        raise ImportError("PyCapsule_Import could not import module") from None
    return 0
sys.exit(contract.run(work))
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    from fpr.cli.interrupts import INTERRUPTED_LINE

    assert (result.returncode, result.stderr) == (130, INTERRUPTED_LINE + "\n")


def test_an_interruption_while_the_options_are_parsed_says_its_line_once():
    """A signal that lands while a command's parser runs: the command says the line and the launcher does not say it
    again (the interruption counts as handled).
    """
    code = (
        "import argparse, sys, types\n"
        "from fpr.cli import interrupts, launch\n"
        "class Parser(argparse.ArgumentParser):\n"
        "    def parse_args(self, args=None, namespace=None):\n"
        "        interrupts.on_signal(2, None)\n"
        "def parser():\n"
        "    p = Parser()\n"
        "    p.add_argument('--debug', action='store_true')\n"
        "    return p\n"
        "fake = types.ModuleType('fake')\n"
        "fake.parser, fake.work = parser, lambda args, argv: 0\n"
        "sys.modules['fake'] = fake\n"
        "interrupts.handle_signals()\n"
        "sys.exit(launch.launch('fake:parser', 'fake:work', []))\n")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 130
    assert run.stderr.splitlines() == [run.stderr.splitlines()[0]] and run.stderr.startswith("interrupted"), run.stderr
