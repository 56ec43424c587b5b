"""``python -m fpr.plan --simulate --replan`` (fpr/cli/replanning.py): files, exit codes, same bytes twice."""

import csv
import json

import numpy as np
import pytest

from fpr.cli.plan import main

S0 = "3.9269908169872414, 1.5707963267948966"
MISSION = f"""robot = "fpr"
way_points = [[0.0, 0.0, {S0}], [0.5, 0.0, {S0}], [0.5, 0.5, {S0}]]
times = [2.0, 2.0]
via_points = 1

[[events]]
at = 2.5
kind = "move"
way_point = 2
to = [0.6, 0.4, {S0}]
"""


def _csv(path):
    with open(path, encoding="utf-8") as stream:
        rows = list(csv.reader(stream))
    return rows[0], np.array(rows[1:], dtype=float)


def _run(tmp_path, name, *extra):
    mission = tmp_path / "short.toml"
    mission.write_text(MISSION, encoding="utf-8")
    out = tmp_path / name
    code = main(
        [
            "--mission",
            str(mission),
            "--method",
            "none",
            "--simulate",
            "--hold",
            "0",
            "--no-plots",
            "--quiet",
            "--rate",
            "100",
            "--out",
            str(out),
            *extra,
        ]
    )
    return code, out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("replan")
    return {
        # a deadline that a slow machine meets (guides/replanning)
        "replan": _run(tmp, "a", "--replan", "--replan-deadline", "0.25"),
        "again": _run(tmp, "b", "--replan", "--replan-deadline", "0.25"),
        "plain": _run(tmp, "c"),
    }


def test_replanned_run_follows_the_moved_way_point(runs):
    code, out = runs["replan"]
    assert code == 0
    document = json.loads((out / "replans.json").read_text())
    [record] = document["replans"]
    assert record["used"] and record["feasible"] and record["start"] == "plan"
    assert (
        record["splice_time"] == pytest.approx(2.5 + 0.25) and "solve_wall_s" not in record
    )  # wall times: manifest
    assert "replan 0" in json.loads((out / "manifest.json").read_text())["timings_s"]
    names, data = _csv(out / "trajectory.csv")
    at = int(np.argmin(np.abs(data[:, 0] - 4.0)))
    planned = data[at, [names.index("y"), names.index("z")]]
    simulated = data[at, [names.index("sim_y"), names.index("sim_z")]]
    np.testing.assert_allclose(planned, [0.6, 0.4], atol=1e-9)  # the planned columns: the plan in force
    assert np.linalg.norm(simulated - [0.6, 0.4]) < 0.02


def test_closed_loop_margins_are_measured_against_the_executed_plan(runs):
    """simulation.json's planned margins are the executed plan's (rebuilt from replans.json), not the offline's."""
    from fpr.robots import load
    from planners.problem.report import evaluate_motion
    from planners.trajectory.polynomial import PiecewisePolynomial

    (_, out), (_, plain) = runs["replan"], runs["plain"]
    executed = json.loads((out / "replans.json").read_text())["executed_plan"]
    trajectory = PiecewisePolynomial(np.array(executed["points"]), np.diff(executed["knots_s"]))
    report = evaluate_motion(load("fpr"), trajectory, 500.0)
    margins = json.loads((out / "simulation.json").read_text())["constraints"]
    offline = json.loads((plain / "simulation.json").read_text())["constraints"]
    for name, entry in margins.items():
        assert entry["planned_margin"] == pytest.approx(report.constraints[name].margin, rel=1e-9, abs=1e-12), name
    assert any(abs(margins[n]["planned_margin"] - offline[n]["planned_margin"]) > 1e-6 for n in margins)


def test_without_replan_the_move_is_ignored(runs):
    code, out = runs["plain"]
    assert code == 0 and not (out / "replans.json").exists()
    names, data = _csv(out / "trajectory.csv")
    at = int(np.argmin(np.abs(data[:, 0] - 4.0)))
    np.testing.assert_allclose(data[at, [names.index("y"), names.index("z")]], [0.5, 0.5], atol=1e-9)
    simulated = data[at, [names.index("sim_y"), names.index("sim_z")]]
    assert np.linalg.norm(simulated - [0.6, 0.4]) > 0.1


def test_same_command_same_bytes(runs):
    (_, a), (_, b) = runs["replan"], runs["again"]
    for name in ("replans.json", "trajectory.csv", "plan.json"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--replan"], "add --simulate"),
        (["--simulate", "--replan", "--replan-deadline", "0"], "--replan-deadline"),
        (["--simulate", "--replan", "--replan-rate", "nan"], "--replan-rate"),
        (["--simulate", "--replan", "--mission", "cross-singularity"], "singularity-crossing"),
    ],
)
def test_bad_replan_options_exit_2_with_one_line(tmp_path, capsys, argv, words):
    code = main([*argv, "--out", str(tmp_path / "x"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_a_moved_way_point_out_of_reach_exits_2_before_any_work(tmp_path, capsys):
    mission = tmp_path / "bad.toml"
    mission.write_text(MISSION.replace("to = [0.6, 0.4,", "to = [0.6, 0.4, 3.0, 1.5]  # phi out of range\n# "),
                       encoding="utf-8")
    code = main(["--mission", str(mission), "--simulate", "--out", str(tmp_path / "x"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "events[0].to" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_a_deadline_no_solve_meets_moves_the_splice_to_when_the_solve_is_ready(tmp_path, capsys):
    """A 1 ms deadline: the change is not dropped; it is spliced when its first iteration is ready on this
    machine (the tests' pinned latency model), and the record and the summary say so.
    """
    mission = tmp_path / "short.toml"
    mission.write_text(MISSION, encoding="utf-8")
    code = main(["--mission", str(mission), "--method", "none", "--simulate", "--hold", "0", "--no-plots",
                 "--rate", "100", "--out", str(tmp_path / "late"), "--replan", "--replan-deadline", "0.001"])
    out = capsys.readouterr().out
    document = json.loads((tmp_path / "late" / "replans.json").read_text())
    [record] = document["replans"]
    assert code == 0 and record["used"] and record["delayed_s"] > 0
    assert record["splice_time"] == pytest.approx(2.5 + 0.001 + record["delayed_s"])
    assert record["latency_s"] <= record["splice_time"] - record["time"] + 1e-12
    assert "past the 1 ms deadline" in record["why"] and "past the 1 ms deadline" in out
    assert document["latency_model"]["source"] == "the tests' pinned model"


def test_a_run_pinned_to_a_calibration_gives_the_same_bytes(tmp_path):
    """--replan-calibration FILE: the decisions depend on that file only. Two runs pinned to the same model
    (a calibration file, and the replans.json of the first run) write the same bytes, whatever this
    machine's own calibration holds; a slower model delays the splice.
    """
    slow = tmp_path / "slow.json"
    slow.write_text(json.dumps({"latency_model": {"costs": [0.0, 0.0, 0.004, 0.0, 0.0], "source": "slow"}}),
                    encoding="utf-8")
    first = _run(tmp_path, "a", "--replan", "--replan-calibration", str(slow))
    again = _run(tmp_path, "b", "--replan", "--replan-calibration", str(first[1] / "replans.json"))
    assert first[0] == again[0] == 0
    for name in ("replans.json", "trajectory.csv", "simulation.json"):
        assert (first[1] / name).read_bytes() == (again[1] / name).read_bytes(), name
    [record] = json.loads((first[1] / "replans.json").read_text())["replans"]
    assert record["used"] and record["delayed_s"] > 0  # 21 nodes x 4 ms > the 50 ms deadline


@pytest.mark.parametrize("content, words", [("not json", "cannot read"), ('{"robots": {}}', "no replanning latency"),
                                            ('{"latency_model": {"costs": [-1, 0, 0, 0, 0]}}', "no replanning")])
def test_a_bad_calibration_file_exits_2_with_one_line(tmp_path, capsys, content, words):
    bad = tmp_path / "bad.json"
    bad.write_text(content, encoding="utf-8")
    code = main(["--simulate", "--replan", "--replan-calibration", str(bad), "--out", str(tmp_path / "x"),
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and words in err and "--replan-calibration" in err and len(err.strip().splitlines()) == 1
