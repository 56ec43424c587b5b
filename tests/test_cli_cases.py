"""``python -m fpr.plan``: what a new user broke, each case ending as the contract says (in-process runs).

Exit codes (:mod:`fpr.cli.contract`): 0 success, 1 the result breaks a limit, 2 bad input (one line naming the
option or field and what to give), 3 internal error, 130 interrupted.
"""

from __future__ import annotations

import errno
import json
import math
import time
import zipfile

import numpy as np
import pytest

from fpr.cli import checks, contract, output
from fpr.cli import plan as cli
from fpr.cli.plan import main
from fpr.cli.plan_options import REPLAN_DEFAULTS, SIMULATION_DEFAULTS, parser
from fpr.cli.text import length, plural, short_list
from fpr.sim.closed_loop import SimulationLog

FAST = ("--no-plots", "--quiet", "--rate", "20")
S0 = [0.0, 0.0, 3.9269908169872414, 1.5707963267948966]


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _file(tmp_path, text, name="m.toml", encoding="utf-8"):
    path = tmp_path / name
    path.write_text(text, encoding=encoding)
    return path


def _mission(points, times, extra=""):
    return (f'robot = "fpr"\nway_points = {points!r}\ntimes = {times!r}\n' + extra)


HOVER = _mission([S0, S0], [3.0])
VERTICAL = _mission([S0, [0.0, 0.5, S0[2], S0[3]]], [3.0])


# ------------------------------------------------------------------------------------------- travel times
@pytest.mark.parametrize("times, words", [
    ("1e-3", ["--times", "times[0] = 0.001 s", "check grid", "give at least 0.004 s"]),
    ("1e-300", ["--times", "times[0] = 1e-300 s", "give at least 0.004 s"]),
    ("5e-324", ["--times", "give at least 0.004 s"]),
    ("0.01", ["--times", "too short for the robot's rotors", "full thrust", "give at least 0.3"]),
], ids=["1e-3", "1e-300", "subnormal", "0.01"])
def test_a_travel_too_short_is_refused_up_front(tmp_path, capsys, times, words):
    start = time.perf_counter()
    code, _, err = _run(capsys, "--times", times, *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and line.startswith("error:"), err
    for word in words:
        assert word in line, (word, line)
    assert not (tmp_path / "out").exists()
    assert time.perf_counter() - start < 30.0  # before the work (100 s for 1e-300 before this check)


def test_the_travel_floor_is_below_every_feasible_plan_of_the_built_in_missions():
    """The rotors' floor (least_travel_times) refuses only what cannot be flown: the built-in missions' travels
    are far above it, and the square planned at its floor (uniform times) breaks a limit.
    """
    from planners.missions.mission import load_mission
    from planners.optimize import plan

    for name in ("square", "study", "prototype-tour", "moving-target"):
        mission = load_mission(name)
        least = checks.least_travel_times(mission, mission.load_robot())
        assert np.all(least > 0) and np.all(mission.times > 3 * least), (name, least)
    square = load_mission("square")
    floor = float(checks.least_travel_times(square, square.load_robot()).max())
    assert not plan(square.replace(times=[floor] * 4), "none").feasible


def test_the_travel_floor_scales_as_the_physics_says():
    """Half the distance needs 1/sqrt(2) of the time (pure translation, same pose): F = G + H / T^2 with H
    proportional to the distance.
    """
    from planners.missions.mission import Mission

    def floor(d):
        mission = Mission(name="m", robot="fpr", way_points=[S0, [d, 0.0, S0[2], S0[3]]], times=[3.0])
        return float(checks.least_travel_times(mission, mission.load_robot())[0])

    assert floor(0.5) / floor(1.0) == pytest.approx(1 / math.sqrt(2), rel=1e-6)
    hover = Mission(name="m", robot="fpr", way_points=[S0, S0], times=[3.0])
    assert checks.least_travel_times(hover, hover.load_robot())[0] == 0.0


# --------------------------------------------------------------------------------------- the hover, J's floors
@pytest.mark.parametrize("method", ["none", "two-step"])
def test_a_hover_is_a_valid_mission(tmp_path, capsys, method):
    out = tmp_path / "out"
    code, stdout, err = _run(capsys, "--mission", _file(tmp_path, HOVER), "--method", method, *FAST[:1],
                             "--rate", "20", "--out", out)
    assert code == 0, err
    assert "1 travel," in stdout
    summary = json.loads((out / "plan.json").read_text())["summary"]
    assert summary["J_e0"] == 0.0 and summary["J_phi0"] == 0.0
    assert summary["J"] == 0.0 and all(v > 0 for v in summary["J_normalisation"])  # nothing to gain


def test_a_vertical_travel_normalises_j_phi_by_its_floor(tmp_path, capsys):
    """The FPR moving straight up keeps its rolls: J_phi0 is round-off (about 1e-33), J uses its floor."""
    from fpr import load
    from planners.result import normalisation_floors

    out = tmp_path / "out"
    code, _, err = _run(capsys, "--mission", _file(tmp_path, VERTICAL), "--no-plots", "--quiet", "--out", out)
    assert code == 0, err
    summary = json.loads((out / "plan.json").read_text())["summary"]
    reference = json.loads((out / "plan.json").read_text())["reference_summary"]
    assert summary["J_phi0"] < 1e-20
    floors = normalisation_floors(load("fpr"), 3.0)
    assert summary["J_normalisation"] == pytest.approx([summary["J_e0"], floors[1]])
    assert math.isfinite(summary["J"]) and summary["J"] <= reference["J"] + 1e-9


def test_the_floors_leave_the_thesis_normalisation_of_the_built_in_missions():
    from planners.missions.mission import load_mission
    from planners.optimize import plan

    for name in ("square", "study", "prototype-tour"):
        result = plan(load_mission(name), "none")
        assert result.normalisation == (result.reference.J_e, result.reference.J_phi)
        assert result.J == pytest.approx(1.0, abs=1e-12)


# --------------------------------------------------------------------------------------------- robot ranges
@pytest.mark.parametrize("assignment, words", [
    ("drone_mass=1e-300", ["--set drone_mass=1e-300", "physical range [0.01, 100] kg"]),
    ("drone_mass=5e-324", ["--set drone_mass", "physical range"]),
    ("drone_mass=1e300", ["--set drone_mass", "physical range"]),
    ("link_length=1e-300", ["--set link_length", "physical range [0.05, 10] m"]),
    ("link_mass=1e-300", ["--set link_mass", "physical range"]),
    ("end_effector_mass=1e-300", ["--set end_effector_mass", "0 or [0.001, 100] kg"]),
    ("hinge_offset=1e-300", ["--set hinge_offset", "0 or [0.001, 2] m"]),
    ("drone_ixx=1e-300", ["--set drone_ixx", "physical range"]),
    ("rotor_arm=-0", ["--set rotor_arm", "physical range"]),
], ids=lambda v: v if isinstance(v, str) else None)
def test_robot_parameters_outside_their_physical_range_exit_2(tmp_path, capsys, assignment, words):
    code, _, err = _run(capsys, "--set", assignment, "--method", "none", *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2, err
    for word in words:
        assert word in line, (word, line)


def test_zero_stays_allowed_where_the_part_may_be_absent(tmp_path, capsys):
    code, _, err = _run(capsys, "--mission", "study", "--set", "end_effector_mass=0", "--set", "hinge_offset=-0.0",
                        "--method", "none", *FAST, "--out", tmp_path / "out")
    assert code == 0, err


def test_a_mission_file_robot_parameter_is_checked_where_it_is_written(tmp_path, capsys):
    path = _file(tmp_path, HOVER + "[robot_parameters]\ndrone_mass = 1e-300\n")
    code, _, err = _run(capsys, "--mission", path, "--method", "none", *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and "robot_parameters.drone_mass" in line and "physical range" in line


# -------------------------------------------------------------------------------------------- events
def test_a_gust_on_a_drone_the_robot_has_not_exits_2(tmp_path, capsys):
    text = builtin("gust").replace('body = "end_effector"', 'body = "drone_3"')
    if 'body = "drone_3"' not in text:
        text += '\n[[events]]\nat = 1.0\nkind = "gust"\nforce = [0.0, 1.0, 0.0]\nduration = 1.0\nbody = "drone_3"\n'
    code, _, err = _run(capsys, "--mission", _file(tmp_path, text), "--method", "none", "--simulate", *FAST,
                        "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and "events[" in line and "].body" in line and "has 2 drone(s)" in line, err


@pytest.mark.parametrize("key, value, words", [("duration", "1e-300", ["events[0].duration", "at least 0.001 s"]),
                                              ("rise", "1e-300", ["events[0].rise", "0 (a step)"])])
def test_a_gust_shorter_than_a_step_of_the_simulation_exits_2(tmp_path, capsys, key, value, words):
    event = {"duration": "2.0", "rise": "0.0"} | {key: value}
    text = HOVER + ("\n[[events]]\nat = 1.0\nkind = \"gust\"\nforce = [0.0, 1.0, 0.0]\n"
                    f"duration = {event['duration']}\nrise = {event['rise']}\n")
    code, _, err = _run(capsys, "--mission", _file(tmp_path, text), "--method", "none", *FAST, "--out", tmp_path / "o")
    line = _one_line(err)
    assert code == 2
    for word in words:
        assert word in line, (word, line)


def builtin(name):
    from planners.missions.mission import builtin_mission_text

    return builtin_mission_text(name)


# ------------------------------------------------------------------------------------------- mission files
def test_a_device_is_not_read_to_its_end(tmp_path, capsys):
    start = time.perf_counter()
    code, _, err = _run(capsys, "--mission", "/dev/zero", *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and "/dev/zero" in line and "larger than" in line
    assert "--rate" not in line and "--times" not in line
    assert time.perf_counter() - start < 10.0


def test_a_huge_mission_gets_a_short_line(tmp_path, capsys):
    points = [[0.5 + 0.3 * math.cos(a), 0.5 + 0.3 * math.sin(a), S0[2], S0[3]] for a in np.linspace(0, 200, 20000)]
    path = _file(tmp_path, _mission(points, [3.0] * 19999))
    code, _, err = _run(capsys, "--mission", path, "--method", "none", *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and "times" in line and "19999 values" in line
    assert len(line) <= contract.MAX_LINE + 100


def test_a_byte_order_mark_is_accepted(tmp_path, capsys):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + HOVER.encode("utf-8"))
    code, _, err = _run(capsys, "--mission", path, "--method", "none", *FAST, "--out", tmp_path / "out")
    assert code == 0, err


@pytest.mark.parametrize("encoding, words", [("utf-16", ["UTF-16", "save it as UTF-8"]),
                                             ("latin-1", ["not UTF-8", "line 1"])])
def test_other_encodings_say_what_is_wrong(tmp_path, capsys, encoding, words):
    path = _file(tmp_path, "description = \"é\"\n" + HOVER, encoding=encoding)
    code, _, err = _run(capsys, "--mission", path, *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2
    for word in words:
        assert word in line, (word, line)


@pytest.mark.parametrize("text, words", [
    ("a" + ".a" * 10000 + " = 1\n", ["dotted parts"]),
    ("a = " + "[" * 5000 + "]" * 5000 + "\n", ["nested too deeply"]),
    ("robot = \"fpr\"\nway_points = [[0,0,3.9,1.5],[0,0,3.9,1.5]]\ntimes = [3.0]\nvia_points = " + "9" * 400 + "\n",
     ["via_points", "at most 1000"]),
], ids=["deep-key", "deep-array", "huge-integer"])
def test_pathological_toml_is_refused_quickly(tmp_path, capsys, text, words):
    start = time.perf_counter()
    code, _, err = _run(capsys, "--mission", _file(tmp_path, text), *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2, err
    for word in words:
        assert word in line, (word, line)
    assert time.perf_counter() - start < 10.0  # (the deep key took 400 MB per 10,000 parts in tomllib)


# ----------------------------------------------------------------------------------------------- full disk
def test_a_disk_too_small_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(output.shutil, "disk_usage", lambda path: type("u", (), {"free": 1000})())
    code, _, err = _run(capsys, "--mission", "study", "--method", "none", *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and "--out" in line and "1 kB free" in line and "writes about" in line
    assert not (tmp_path / "out").exists() and [p.name for p in tmp_path.iterdir()] == []


def test_a_disk_that_fills_up_names_out_and_the_space_needed(tmp_path, capsys, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(cli, "write_csv", full)
    code, _, err = _run(capsys, "--mission", "study", "--method", "none", *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and "--out" in line and "No space left on device" in line and "writes about" in line
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------------------------ options and --simulate
def test_a_negative_number_reaches_the_toolkit_s_message(tmp_path, capsys):
    for argv in (["--times", "-1,1,1,1"], ["--times=-1,1,1,1"]):
        code, _, err = _run(capsys, *argv, *FAST, "--out", tmp_path / "out")
        line = _one_line(err)
        assert code == 2 and "times[0] = -1" in line and "> 0" in line, line
    code, _, err = _run(capsys, "--simulate", "--wind", "-1e300,0,0", *FAST, "--out", tmp_path / "out")
    assert code == 2 and "--wind" in _one_line(err) and ">= -1000" in err


@pytest.mark.parametrize("option", [opt for opt, _ in {**SIMULATION_DEFAULTS, **REPLAN_DEFAULTS}.values()])
def test_every_simulation_option_needs_simulate(tmp_path, capsys, option):
    value = {"--initial-error": ["y=0.01"], "--wind": ["0,5,0"], "--noise": ["0,0"], "--replan-wind": ["blind"],
             "--replan-timing": ["wall"], "--takeoff": [], "--replan": [], "--no-observer": []}.get(option, ["0.5"])
    code, _, err = _run(capsys, option, *value, *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and line.startswith(f"error: {option}") and "add --simulate" in line, line


@pytest.mark.parametrize("option", [opt for opt, _ in REPLAN_DEFAULTS.values()])
def test_every_replanning_option_needs_replan(tmp_path, capsys, option):
    value = "wall" if option == "--replan-timing" else "0.5"
    code, _, err = _run(capsys, "--simulate", option, value, *FAST, "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2 and line.startswith(f"error: {option}") and "add --replan" in line, line


@pytest.mark.parametrize("argv, words", [
    (["--replan-deadline", "1e-300"], ["--replan-deadline", ">= 0.001"]),
    (["--replan-deadline", "1e300"], ["--replan-deadline", "<= "]),
    (["--replan-rate", "1e300"], ["--replan-rate", "<= 100"]),
    (["--replan-rate", "1e-300"], ["--replan-rate", ">= "]),
    (["--replan-bound", "1e300"], ["--replan-bound", "<= 1"]),
], ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_replanning_numbers_in_their_ranges(tmp_path, capsys, argv, words):
    code, _, err = _run(capsys, "--mission", "study", "--method", "none", "--simulate", "--replan", *argv, *FAST,
                        "--out", tmp_path / "out")
    line = _one_line(err)
    assert code == 2
    for word in words:
        assert word in line, (word, line)


# --------------------------------------------------------------------------------------- the same bytes
def test_simulation_npz_is_the_same_bytes_on_two_runs(tmp_path, capsys):
    files = []
    for name in ("a", "b"):
        code, _, err = _run(capsys, "--mission", "study", "--method", "none", "--simulate", "--hold", "0.2", *FAST,
                            "--out", tmp_path / name)
        assert code == 0, err
        files.append((tmp_path / name / "simulation.npz").read_bytes())
        time.sleep(1.1)  # zip timestamps have a 2 s resolution: make a stamped time differ
    assert files[0] == files[1]
    with zipfile.ZipFile(tmp_path / "a" / "simulation.npz") as archive:
        assert {info.date_time for info in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}
    log = SimulationLog.load(tmp_path / "a" / "simulation.npz")
    assert math.isnan(log.wall_time) and log.t.size > 10
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["timings_s"]["simulation"] > 0  # the wall time is in the manifest


# ---------------------------------------------------------------------------------------------- the texts
def test_help_shows_no_empty_defaults(capsys):
    code, out, _ = _run(capsys, "--help")
    assert code == 0
    assert "(default: None)" not in out and "(default: False)" not in out and "(default: [])" not in out
    assert "(default: 200.0)" in out and "default 1)" in out


def test_the_help_lists_the_registries(capsys):
    """The light parser's lists (read without importing the registries) are the registries'."""
    from fpr.cli.plan_options import HELP_METHODS, REPLAN_TIMINGS
    from planners.methods import METHODS
    from planners.missions import BUILTIN_MISSIONS
    from planners.missions.mission import BUILTIN_MISSIONS as READ
    from planners.replanning.replanner import TIMINGS

    assert tuple(METHODS) == HELP_METHODS and TIMINGS == REPLAN_TIMINGS and BUILTIN_MISSIONS is READ
    assert parser().parse_args(["--method", "one-step"]).method == "one-step"
    code, _, err = _run(capsys, "--method", "three-step")
    assert code == 2 and "invalid choice: 'three-step'" in _one_line(err) and "two-step" in err


def test_a_crossing_says_which_method_plans_it(tmp_path, capsys):
    code, out, err = _run(capsys, "--mission", "cross-singularity", "--method", "none", "--no-plots",
                          "--rate", "20", "--out", tmp_path / "out")
    assert code in (0, 1), err
    assert "method none (the crossing's first guess)" in out


def test_solver_lines_name_the_kkt_residual_once(tmp_path, capsys):
    code, out, err = _run(capsys, "--mission", "study", "--no-plots", "--rate", "20", "--out", tmp_path / "out")
    assert code == 0, err
    solver = [line for line in out.splitlines() if line.strip().startswith("solver ")]
    assert solver and all(line.count("KKT residual") <= 1 for line in solver)
    assert not any(" 1 iterations" in line for line in out.splitlines())


def test_the_simulation_summary_gives_a_height_above_the_ground(tmp_path, capsys):
    code, out, err = _run(capsys, "--mission", "study", "--method", "none", "--simulate", "--hold", "0.2",
                          "--no-plots", "--rate", "20", "--out", tmp_path / "out")
    assert code == 0, err
    line = next(x for x in out.splitlines() if "above the ground" in x)
    height = float(line.split("above the ground ")[1].split()[0])
    assert height > 0  # the study's drones fly above the ground (z = -L), not at a negative "height"


def test_texts_for_people():
    assert plural(1, "travel") == "1 travel" and plural(3, "travel") == "3 travels"
    assert plural(1, "iteration") == "1 iteration" and plural(0, "run") == "0 runs"
    assert length(70.0033) == "70 m" and length(0.0451) == "4.51 cm" and length(0.0032) == "3.2 mm"
    assert length(12345.0) == "12.3 km" and length(-0.5) == "-50 cm"
    assert short_list([3.0] * 20000) == "3,3,3,3,...,3,3 (20000 values)" and short_list([1, 2]) == "1,2"
    assert len(contract.one_line("x" * 50_000)) <= contract.MAX_LINE
    assert "characters left out" in contract.one_line("x" * 50_000)


def test_way_points_in_messages_are_rounded(tmp_path, capsys):
    far = _mission([S0, [0.0, -5.123456789, S0[2], S0[3]]], [3.0])  # under the ground
    code, _, err = _run(capsys, "--mission", _file(tmp_path, far), "--method", "none", *FAST, "--out", tmp_path / "o")
    line = _one_line(err)
    assert code == 2 and "-5.12346" in line and "5.123456789" not in line and "3.9269908169872414" not in line


def test_library_warnings_do_not_reach_the_user_but_debug_shows_them(tmp_path, capsys, monkeypatch):
    import warnings

    real = cli.plan

    def noisy(*args, **kwargs):
        warnings.warn("overflow encountered in multiply", RuntimeWarning, stacklevel=2)
        return real(*args, **kwargs)

    monkeypatch.setattr(cli, "plan", noisy)
    code, _, err = _run(capsys, "--mission", "study", "--method", "none", *FAST, "--out", tmp_path / "a")
    assert code == 0 and err == ""
    code, _, err = _run(capsys, "--mission", "study", "--method", "none", *FAST, "--out", tmp_path / "b", "--debug")
    assert code == 0 and "RuntimeWarning" in err


def test_the_parameter_ranges_hold_the_default_robots():
    from fpr.model.parameters import PARAMETER_RANGES, load_parameters

    defaults = load_parameters()
    for key, bounds in PARAMETER_RANGES.items():
        assert bounds.contains(float(defaults[key])), key


def test_sizes_for_people():
    assert output.size_text(1000) == "1 kB" and output.size_text(3.2e6) == "3.2 MB"
