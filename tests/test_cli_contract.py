"""``python -m fpr.plan``'s contract: exit codes, one-line messages, checks before the work, atomic output.

Exit codes: 0 success, 1 the result breaks a limit, 2 bad input, 3 internal error, 130 interrupted
(:mod:`fpr.cli.contract`). Every failing case here fails before any work, so each runs in well under a second.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fpr.cli import plan as cli
from fpr.cli.plan import main
from fpr.sim.plant import PlantDivergedError
from planners.missions.mission import builtin_mission_text

ROOT = Path(__file__).resolve().parents[1]
FAST = ("--method", "none", "--no-plots", "--quiet", "--rate", "20")


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _leftovers(parent: Path) -> list[str]:
    return [p.name for p in parent.iterdir() if ".tmp-" in p.name or ".old-" in p.name]


def _mission_file(tmp_path, text, name="m.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def previous(tmp_path, capsys):
    """A complete run in tmp_path / "out" (the folder a later failed run must leave as it is)."""
    out = tmp_path / "out"
    code, _, err = _run(capsys, "--mission", "study", *FAST, "--out", out)
    assert code == 0, err
    return out, _snapshot(out)


# ------------------------------------------------------------------------------------------ bad input: exit 2
BAD_OPTIONS = [
    (["--times", "1e9"], ["--times", "limit", "200,000", "shorter"]),
    (["--times", "nan"], ["--times", "finite"]),
    (["--times", "inf"], ["--times", "finite"]),
    (["--times", "3,0"], ["--times", "times[1]", "> 0"]),
    (["--rate", "1e9"], ["--rate", "rows", "limit", "or less"]),
    (["--rate", "0"], ["--rate", "> 0"]),
    (["--rate", "-5"], ["--rate", "> 0"]),
    (["--rate", "nan"], ["--rate", "finite"]),
    (["--rate", "abc"], ["--rate", "invalid float"]),
    (["--alpha", "2"], ["--alpha", "<= 1"]),
    (["--alpha", "nan"], ["--alpha", "finite"]),
    (["--via-points", "-1"], ["--via-points", ">= 0"]),
    (["--via-points", "1.5"], ["--via-points", "integers"]),
    (["--set", "drone_mass=0"], ["--set drone_mass", "range"]),
    (["--set", "drone_mass=-1"], ["--set drone_mass=-1", ">= 0"]),
    (["--set", "drone_mass=5"], ["drone_mass", "rotors lift", "at most"]),
    (["--set", "link_length=1e6"], ["--set link_length", "range"]),
    (["--set", "link_length=0"], ["link_length"]),
    (["--set", "link_mass=nan"], ["--set link_mass=nan", "finite"]),
    (["--set", "drone_ixx=1"], ["drone_ixx", "inertia"]),
    (["--set", "rotor_thrust_coefficient=1"], ["rotor_thrust_coefficient", "unknown robot parameter"]),
    (["--set", "drone_mass"], ["--set", "NAME=VALUE"]),
    (["--simulate", "--model-mass-scale", "0"], ["--model-mass-scale", ">= 0.01", "factor 100"]),
    (["--simulate", "--model-mass-scale", "-1"], ["--model-mass-scale", ">= 0.01"]),
    (["--simulate", "--rotor-constant-scale", "0"], ["--rotor-constant-scale", ">= 0.01"]),
    (["--simulate", "--rotor-constant-scale", "inf"], ["--rotor-constant-scale", "finite"]),
    (["--simulate", "--wind", "1,2"], ["--wind", "three"]),
    (["--simulate", "--wind", "1,2,nan"], ["--wind", "finite"]),
    (["--simulate", "--wind", "a,b,c"], ["--wind", "numbers"]),
    (["--simulate", "--noise=-0.01,-0.01"], ["--noise", ">= 0"]),
    (["--simulate", "--noise", "0.1"], ["--noise", "two"]),
    (["--simulate", "--hold", "-1"], ["--hold", ">= 0"]),
    (["--simulate", "--hold", "1000"], ["--hold", "<= 300"]),
    (["--simulate", "--hold", "290"], ["--simulate", "limit", "300"]),
    (["--simulate", "--initial-error", "bogus=1"], ["--initial-error", "unknown coordinate", "q21"]),
    (["--simulate", "--initial-error", "y=nan"], ["--initial-error y=nan", "finite"]),
    (["--mission", "study", "--method", "two-step", "--via-points", "100"], ["--via-points", "segments", "limit"]),
    (["--mission", "no-such-mission"], ["square"]),
    (["--robot", "prototype"], ["'fpr'"]),
    (["--method", "crossing"], ["cross_singularity"]),
    (["--method", "three-step"], ["invalid choice"]),
    (["--no-such-option"], ["unrecognized"]),
]


@pytest.mark.parametrize("argv, words", BAD_OPTIONS, ids=[" ".join(a) for a, _ in BAD_OPTIONS])
def test_bad_option_exits_2_with_one_line_before_any_work(tmp_path, capsys, argv, words):
    start = time.perf_counter()
    code, _, err = _run(capsys, *argv, "--no-plots", "--quiet", "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2, err
    assert line.startswith("error:")
    for word in words:
        assert word in line, (word, line)
    assert not (tmp_path / "out").exists() and not _leftovers(tmp_path)
    assert time.perf_counter() - start < 10.0  # refused before the work, not after it


def test_bad_option_leaves_the_previous_folder(previous, capsys):
    out, before = previous
    code, _, _ = _run(capsys, "--rate", "1e9", *FAST[:-2], "--out", out)
    assert code == 2 and _snapshot(out) == before


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace("via_points = 1", "via_points = 1000"),
     ["field 'via_points' = 1000", "segments", "limit is 64"]),
    (lambda t: t.replace("times = [3.0]", "times = [1e9]"), ["field 'times' = 1e+09", "limit"]),
    (lambda t: t.replace("[robot_parameters]", "[robot_parameters]\ndrone_mass = 0.0"),
     ["robot_parameters.drone_mass", "range"]),
    (lambda t: t.replace("[robot_parameters]", "[robot_parameters]\nlink_length = 1e6"),
     ["robot_parameters.link_length", "range"]),
    (lambda t: t.replace("[robot_parameters]", "[robot_parameters]\nlink_length = \"long\""),
     ["robot_parameters.link_length", "finite number"]),
    (lambda t: t.replace("alpha = 0.5", "alpha = nan"), ["alpha", "[0, 1]"]),
    (lambda t: t.replace("times = [3.0]", "times = [inf]"), ["times[0]", "finite"]),
    (lambda t: t.replace("via_points = 1", "via_points = -2"), ["via_points", ">= 0"]),
    (lambda t: t.replace("via_points = 1", "via_points = 1.5"), ["via_points", "integer"]),
    (lambda t: t.replace("[0.0, 0.0, 3.9270, 1.5708]", "[0.0, nan, 3.9270, 1.5708]"), ["way_points[0]", "finite"]),
    (lambda t: t.replace("[0.0, 0.0, 3.9270, 1.5708]", "[0.0, 0.0, 3.9270]"), ["way_points[0]", "entries"]),
    (lambda t: "speed = 3\n" + t, ["speed", "unknown key"]),
    (lambda t: t.replace('robot = "fpr"', ""), ["robot", "missing"]),
    (lambda t: "\x00\x01", ["<toml>"]),
], ids=["via_points-1000", "times-1e9", "drone_mass-0", "link_length-1e6", "link_length-text", "alpha-nan",
        "times-inf", "via_points-negative", "via_points-float", "way_point-nan", "way_point-short", "unknown-key",
        "no-robot", "binary"])
def test_bad_mission_file_exits_2(tmp_path, capsys, edit, words):
    text = edit(builtin_mission_text("study"))
    path = _mission_file(tmp_path, text)
    code, _, err = _run(capsys, "--mission", path, "--method", "two-step", "--no-plots", "--quiet",
                        "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2, err
    for word in words:
        assert word in line, (word, line)
    assert not (tmp_path / "out").exists()


def test_unreadable_mission_file_exits_2(tmp_path, capsys):
    code, _, err = _run(capsys, "--mission", tmp_path, *FAST, "--out", tmp_path / "out")  # a folder
    assert code == 2 and "cannot read" in _one_line(err)


@pytest.mark.parametrize("make, words", [
    (lambda p: (p / "afile").write_text("x") and p / "afile", ["existing file"]),
    (lambda p: (p / "afile").write_text("x") and p / "afile" / "sub", ["cannot create", "Not a directory"]),
    (lambda p: Path("/proc/fpr-out"), ["cannot create"]),
    (lambda p: p / ("a" * 300), ["shorter name"]),
    (lambda p: p / ("a" * 300) / "sub", ["shorter name"]),
], ids=["existing-file", "under-a-file", "pseudo-file-system", "name-too-long", "parent-name-too-long"])
def test_bad_out_exits_2(tmp_path, capsys, make, words):
    out = make(tmp_path)
    code, _, err = _run(capsys, "--mission", "study", *FAST, "--out", out)
    line = _one_line(err)
    assert code == 2 and "--out" in line, err
    for word in words:
        assert word in line
    assert not _leftovers(tmp_path)


def test_read_only_out_exits_2(tmp_path, capsys, monkeypatch):
    """A read-only disk (root ignores chmod, so the refusal is simulated where the folder is made)."""
    def refuse(*args, **kwargs):
        raise PermissionError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr("fpr.cli.output.tempfile.mkdtemp", refuse)
    code, _, err = _run(capsys, "--mission", "study", *FAST, "--out", tmp_path / "out")
    assert code == 2 and "Read-only file system" in _one_line(err)
    assert not (tmp_path / "out").exists()


def test_a_folder_that_is_not_a_run_is_not_replaced(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes")
    code, _, err = _run(capsys, "--mission", "study", *FAST, "--out", out)
    assert code == 2 and "does not hold an fpr run" in _one_line(err)
    assert (out / "notes.txt").read_text() == "my notes" and len(list(out.iterdir())) == 1


# ---------------------------------------------------------------------------------- atomic output, manifest
def test_manifest_and_one_run_per_folder(previous, capsys):
    out, _ = previous
    (out / "stale.png").write_bytes(b"from another run")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["exit_code"] == 0 and manifest["fpr_version"]
    assert manifest["command"][:3] == ["python", "-m", "fpr.plan"] and "study" in manifest["command"]
    assert len(manifest["inputs_sha256"]) == 64 and manifest["started_utc"].endswith("+00:00")
    assert manifest["duration_s"] >= 0 and manifest["files"] == ["mission.toml", "plan.json", "trajectory.csv"]
    assert manifest["timings_s"] and "wall_time" not in (out / "plan.json").read_text()
    # the same inputs into the same folder: one run's files, the same hash; other inputs, another hash
    code, _, _ = _run(capsys, "--mission", "study", *FAST, "--out", out)
    assert code == 0 and not (out / "stale.png").exists()
    again = json.loads((out / "manifest.json").read_text())
    assert again["inputs_sha256"] == manifest["inputs_sha256"]
    code, _, _ = _run(capsys, "--mission", "study", *FAST, "--alpha", "0.3", "--out", out)
    assert json.loads((out / "manifest.json").read_text())["inputs_sha256"] != manifest["inputs_sha256"]
    assert not _leftovers(out.parent)


def test_same_command_same_bytes(tmp_path, capsys):
    """The wall-clock times live in the manifest: plan.json and trajectory.csv repeat byte for byte."""
    files = []
    for name in ("a", "b"):
        code, _, err = _run(capsys, "--mission", "square", "--no-plots", "--quiet", "--rate", "20",
                            "--out", tmp_path / name)
        assert code == 0, err
        files.append({n: (tmp_path / name / n).read_bytes() for n in ("plan.json", "trajectory.csv")})
    assert files[0] == files[1]


@pytest.mark.parametrize("failure, code, words", [
    (KeyboardInterrupt(), 130, ["interrupted", "Ctrl-C"]),
    (ZeroDivisionError("division by zero"), 3, ["internal error", "ZeroDivisionError", "division by zero", "report"]),
    (OSError(errno.ENOSPC, "No space left on device"), 2, ["No space left on device"]),
    (MemoryError(), 2, ["out of memory"]),
], ids=["ctrl-c", "bug", "disk-full", "memory"])
def test_failure_during_the_work_leaves_the_previous_folder(previous, capsys, monkeypatch, failure, code, words):
    out, before = previous

    def fail(*args, **kwargs):
        raise failure

    monkeypatch.setattr(cli, "write_csv", fail)  # after mission.toml and plan.json are written
    result, _, err = _run(capsys, "--mission", "study", *FAST, "--alpha", "0.2", "--out", out)
    line = _one_line(err)
    assert result == code
    for word in words:
        assert word in line
    assert _snapshot(out) == before
    assert not _leftovers(out.parent)


def test_debug_shows_the_traceback_of_a_bug(tmp_path, capsys, monkeypatch):
    def fail(*args, **kwargs):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(cli, "plan", fail)
    code, _, err = _run(capsys, "--mission", "study", *FAST, "--out", tmp_path / "o", "--debug")
    assert code == 3 and "Traceback" in err and "internal error" in err.splitlines()[-1]
    assert not (tmp_path / "o").exists()


def test_help_documents_the_exit_codes(capsys):
    code, out, _ = _run(capsys, "--help")
    assert code == 0
    for text in ("exit codes:", "0    success", "1    the result breaks a limit", "2    bad input",
                 "3    internal error", "130  interrupted", "--debug"):
        assert text in out


# ------------------------------------------------------------------------------------ lost robot: exit 1
def test_lost_robot_exits_1_and_writes_what_it_has(tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = _run(capsys, "--mission", "study", *FAST, "--simulate", "--wind", "0,100,0", "--out", out)
    line = _one_line(err)
    assert code == 1 and "lost the robot" in line and " t = " in line
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["exit_code"] == 1 and "lost the robot" in manifest["outcome"]
    assert (out / "simulation.npz").exists() and (out / "plan.json").exists()


def test_diverged_plant_exits_1_and_writes_the_plan(tmp_path, capsys, monkeypatch):
    def diverge(*args, **kwargs):
        raise PlantDivergedError(0.5, 0.001)

    monkeypatch.setattr(cli, "simulate", diverge)
    out = tmp_path / "out"
    code, _, err = _run(capsys, "--mission", "study", *FAST, "--simulate", "--out", out)
    assert code == 1 and "lost the robot" in _one_line(err) and "t = 0.5 s" in err
    assert (out / "plan.json").exists() and not (out / "simulation.npz").exists()
    assert json.loads((out / "manifest.json").read_text())["exit_code"] == 1


def test_infeasible_plan_exits_1_and_writes_its_folder(tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = _run(capsys, "--times", "0.5", *FAST, "--out", out)
    assert code == 1 and "violates" in _one_line(err)
    assert json.loads((out / "manifest.json").read_text())["exit_code"] == 1


# ------------------------------------------------------------------------------- Ctrl-C on the real command
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_ctrl_c_prints_one_line_and_exits_130(tmp_path, signum):
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_text("{}")  # a previous run
    # a mission that plans for seconds: the signal must reach the work, not the end of a fast plan (the square
    # plans in about 0.4 s here, close to the half second this test waits)
    proc = subprocess.Popen([sys.executable, "-m", "fpr.plan", "--mission", "cross-singularity", "--no-plots",
                             "--out", str(out)],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not _leftovers(tmp_path) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)  # the temporary folder exists: the work has started
    time.sleep(0.5)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("interrupted")
    assert os.listdir(out) == ["manifest.json"] and (out / "manifest.json").read_text() == "{}"
    assert not _leftovers(tmp_path)


def test_a_failed_swap_puts_the_previous_folder_back(previous, monkeypatch):
    """fpr.cli.output.OutputFolder.commit: if the new folder cannot be renamed in, the old one returns."""
    from fpr.cli import output

    out, before = previous
    folder = output.OutputFolder(out)
    tmp = folder.open()
    (tmp / "plan.json").write_text("new")
    real_rename, calls = os.rename, []

    def rename(src, dst):
        calls.append((src, dst))
        if len(calls) == 2:  # the new folder into place
            raise OSError(errno.EXDEV, "Invalid cross-device link")
        real_rename(src, dst)

    monkeypatch.setattr(output.os, "rename", rename)
    with pytest.raises(output.OutputError, match="previous one is left as it was"):
        folder.commit()
    assert _snapshot(out) == before and not _leftovers(out.parent)


def test_same_bytes_whatever_the_hash_seed(tmp_path):
    """The real command under two PYTHONHASHSEED values: plan.json and trajectory.csv identical."""
    files = []
    for seed in ("1", "2"):
        out = tmp_path / seed
        proc = subprocess.run([sys.executable, "-m", "fpr.plan", "--mission", "square", "--no-plots", "--quiet",
                               "--rate", "20", "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                              env={**os.environ, "PYTHONHASHSEED": seed}, timeout=300)
        assert proc.returncode == 0, proc.stderr
        files.append({n: (out / n).read_bytes() for n in ("plan.json", "trajectory.csv")})
    assert files[0] == files[1]


# --- python -m fpr.studies: the same contract -------------------------------------------------------


def test_studies_refuses_a_bad_out_before_the_work(tmp_path, capsys):
    """An --out that is a file: exit 2 and one line at once (not after the minutes of planning)."""
    from fpr.cli import studies

    target = tmp_path / "file"
    target.write_text("mine", encoding="utf-8")
    start = time.perf_counter()
    code = studies.main(["--quick", "--quiet", "--out", str(target)])
    err = capsys.readouterr().err
    assert code == 2 and time.perf_counter() - start < 5
    assert "--out" in _one_line(err) and target.read_text(encoding="utf-8") == "mine"
    assert studies.main(["--bogus"]) == 2
    assert "see python -m fpr.studies --help" in _one_line(capsys.readouterr().err)


def test_studies_keep_wall_times_out_of_studies_json():
    """The planning times go to the manifest, so that studies.json is the same bytes from run to run."""
    from fpr.cli import studies
    from fpr.cli.plan_files import split_timings

    assert studies.split_timings is split_timings  # the mechanism plan.json uses
    doc = {"via": {"cases": [{"J": 1.0, "wall_time": 0.25}, {"J": 2.0, "wall_time": 0.5}]}, "wall_time": 3.0}
    times = split_timings(doc)
    assert doc == {"via": {"cases": [{"J": 1.0}, {"J": 2.0}]}}
    assert times == {"document": 3.0, "via.cases.0": 0.25, "via.cases.1": 0.5}


def test_taking_the_wall_times_out_of_plan_json_leaves_the_result_s_stages_their_times():
    """split_timings edits the plan document in place; the stages' times the CLI prints afterwards (and the
    manifest's) must be the solver's, not the stage record's default 0 (the document holds copies).
    """
    from fpr.cli.plan_files import split_timings
    from planners.missions.mission import load_mission
    from planners.optimize import plan

    result = plan(load_mission("square"), "two-step")
    before = [stage.wall_time for stage in result.stages]
    times = split_timings(result.summary())
    assert all(stage.wall_time > 0 for stage in result.stages if stage.iterations)
    assert [stage.wall_time for stage in result.stages] == before
    assert [times[f"stages.{stage.name}"] for stage in result.stages] == before
