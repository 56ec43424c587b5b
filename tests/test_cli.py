"""``python -m fpr.plan`` end to end: files, columns and units, exit codes and error messages."""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fpr
from fpr.cli.plan import csv_columns, main, parser
from planners.methods import METHODS
from planners.missions.mission import builtin_mission_text

ROOT = Path(__file__).resolve().parents[1]


def _run(capsys, *argv):
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _read_csv(path):
    with open(path, encoding="utf-8") as stream:
        rows = list(csv.reader(stream))
    return rows[0], np.array(rows[1:], dtype=float)


@pytest.fixture(scope="module")
def square_run(tmp_path_factory):
    """One optimised run of the default mission, shared by the tests that read its files."""
    out = tmp_path_factory.mktemp("square")
    code = main(["--out", str(out), "--quiet", "--rate", "50"])
    return code, out


def test_default_mission_runs_and_writes_everything(square_run):
    code, out = square_run
    assert code == 0
    for name in ("mission.toml", "plan.json", "trajectory.csv", "reference.csv", "path.png", "coordinates.png",
                 "energy.png", "perturbation.png", "thrust.png", "roll.png", "rotor_speeds.png"):
        assert (out / name).stat().st_size > 0, name
    plan = json.loads((out / "plan.json").read_text())
    summary = plan["summary"]
    assert plan["method"] == "two-step" and summary["feasible"]
    assert summary["J"] < 1.0 and plan["reference_summary"]["J"] == pytest.approx(1.0, abs=1e-12)
    assert set(summary["constraints"]) >= {"ground_1", "ground_2", "q21_low", "roll_1", "rotor_speed_high_2"}
    # the coefficients reproduce the points: s(knot) of each segment equals its first point's value
    points = np.array(plan["points"])
    coefficients = np.array(plan["coefficients"])
    np.testing.assert_allclose(coefficients[:, 0], points[:-1, 0], atol=1e-12)
    ends = np.array([np.polynomial.polynomial.polyval(d, coefficients[i]) for i, d in enumerate(plan["durations_s"])])
    np.testing.assert_allclose(ends, points[1:, 0], atol=1e-9)


def test_csv_columns_and_documented_units(square_run):
    _, out = square_run
    robot = fpr.load("fpr")
    header, data = _read_csv(out / "trajectory.csv")
    expected = csv_columns(robot)
    assert header == [name for name, _ in expected]
    readme = (ROOT / "docs" / "guides" / "plan-command.md").read_text()
    table = readme[readme.index("| column | unit | meaning |"):]
    for pattern, unit in [("`t`", "s"), ("`y`, `z`, `phi`, `q21`", "m, m, rad, rad"), ("`f{i}`", "N"),
                          ("`w{i}_{m}`", "rad/s"), ("`tau{i}_x`", "N m"), ("`phi{i}`, `phi{i}_d`", "rad, rad/s")]:
        assert re.search(re.escape(pattern) + r"[^|]*\| " + re.escape(unit), table), pattern
    # 50 Hz over the 12 s mission, end included; the columns are what their names say
    assert data.shape == (12 * 50 + 1, len(header))
    col = {name: data[:, i] for i, name in enumerate(header)}
    np.testing.assert_allclose(np.diff(col["t"]), 0.02, atol=1e-9)
    np.testing.assert_allclose(col["y"][[0, -1]], 0.0, atol=1e-9)
    np.testing.assert_allclose(col["y_d"], np.gradient(col["y"], col["t"]), atol=2e-3)  # 2nd-order FD error
    # the drone joints follow from the pose: r1 = p - L u(phi)
    length = robot.link_length
    np.testing.assert_allclose(col["y_j1"], col["y"] - length * np.cos(col["phi"]), atol=1e-8)
    np.testing.assert_allclose(col["z_j2"], col["z"] - length * np.sin(col["phi"] + col["q21"]), atol=1e-8)
    # thrust = c_T sum w^2 for the rotors
    c_t = robot.rotor_constants.thrust_coefficient
    w = np.stack([col[f"w1_{m}"] for m in range(1, 5)], axis=1)
    np.testing.assert_allclose(col["f1"], c_t * np.sum(np.sign(w) * w**2, axis=1), rtol=1e-6)


def test_prototype_columns(tmp_path, capsys):
    code, out, err = _run(capsys, "--mission", "prototype-tour", "--method", "none", "--out", str(tmp_path),
                          "--rate", "20", "--no-plots")
    assert code == 0, err
    header, data = _read_csv(tmp_path / "trajectory.csv")
    assert header[:7] == ["t", "q1", "q2", "q1_d", "q2_d", "q1_dd", "q2_dd"]
    assert "f1" in header and "w1_4" in header and "f2" not in header
    assert not (tmp_path / "path.png").exists()
    assert "stop at way points" in out


def test_overrides_reach_the_plan(tmp_path, capsys):
    code, _, err = _run(capsys, "--mission", "study", "--method", "none", "--times", "4", "--alpha", "0.3",
                        "--set", "link_length=0.8", "--out", str(tmp_path), "--quiet", "--no-plots")
    assert code == 0, err
    mission = json.loads((tmp_path / "plan.json").read_text())["mission"]
    assert mission["times"] == [4.0] and mission["alpha"] == 0.3
    assert mission["robot_parameters"] == {"link_length": 0.8}
    assert "link_length=0.8" not in (tmp_path / "mission.toml").read_text()  # written as TOML, not as an option
    assert "link_length = 0.8" in (tmp_path / "mission.toml").read_text()


def test_infeasible_motion_exits_1_names_the_constraint_and_writes_files(tmp_path, capsys):
    code, _, err = _run(capsys, "--times", "0.5", "--method", "none", "--out", str(tmp_path), "--quiet",
                        "--no-plots")
    assert code == 1
    assert "rotor_speed" in err and "violates" in err
    summary = json.loads((tmp_path / "plan.json").read_text())["summary"]
    assert not summary["feasible"] and any(v.startswith("rotor_speed") for v in summary["violated"])
    assert (tmp_path / "trajectory.csv").exists()


def _mission_file(tmp_path, text):
    path = tmp_path / "m.toml"
    path.write_text(text, encoding="utf-8")
    return str(path)


@pytest.mark.parametrize("edit, expected", [
    (lambda t: t.replace("times = [", "times = [-1.0, "), "times"),
    (lambda t: t + "\nthis is not toml\n", "<toml>"),
    (lambda t: t.replace('robot = "fpr"', 'robot = "fpr9"'), "robot"),
], ids=["negative-time", "malformed-toml", "unknown-robot"])
def test_bad_mission_file_exits_2_naming_the_field(tmp_path, capsys, edit, expected):
    text = edit(builtin_mission_text("square"))
    code, _, err = _run(capsys, "--mission", _mission_file(tmp_path, text), "--out", str(tmp_path / "o"))
    assert code == 2
    assert expected in err and err.startswith("error:")
    assert not (tmp_path / "o").exists()


def test_negative_time_option_and_unknown_mission(tmp_path, capsys):
    code, _, err = _run(capsys, "--times", "3,-1,3,3", "--out", str(tmp_path))
    assert code == 2 and "times[1]" in err
    code, _, err = _run(capsys, "--mission", "no-such-mission", "--out", str(tmp_path))
    assert code == 2 and "square" in err  # the message lists the built-ins
    code, _, err = _run(capsys, "--robot", "prototype", "--out", str(tmp_path))
    assert code == 2 and "'fpr'" in err


def test_method_choices_are_the_registry(tmp_path, capsys):
    for name in METHODS:
        assert parser().parse_args(["--method", name]).method == name
    with pytest.raises(SystemExit):
        parser().parse_args(["--method", "three-step"])
    assert "invalid choice" in capsys.readouterr().err
    code, _, err = _run(capsys, "--method", "crossing", "--out", str(tmp_path))  # square: no crossing
    assert code == 2 and "cross_singularity" in err and not (tmp_path / "plan.json").exists()


def test_unreachable_and_singular_way_points(tmp_path, capsys):
    tour = builtin_mission_text("prototype-tour")
    far = tour.replace("[1.0, 0.0]", "[3.0, 0.0]")
    assert far != tour
    code, _, err = _run(capsys, "--mission", _mission_file(tmp_path, far), "--out", str(tmp_path / "o"))
    assert code == 2 and "way_points[1]" in err and "workspace" in err
    singular = builtin_mission_text("study").replace("1.5708]", "0.05]", 1)
    code, _, err = _run(capsys, "--mission", _mission_file(tmp_path, singular), "--out", str(tmp_path / "o"))
    assert code == 2 and "singularity" in err and "way_points[0]" in err


def test_module_entry_point(tmp_path):
    """The real command (a new interpreter), as a user runs it."""
    proc = subprocess.run([sys.executable, "-m", "fpr.plan", "--mission", "study", "--method", "one-step",
                           "--out", str(tmp_path), "--no-plots", "--rate", "20"],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "optimised (one-step)" in proc.stdout and "iteration" in proc.stderr
