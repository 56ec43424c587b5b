"""Missions: built-in files against DESIGN.md, validation field by field, TOML round trip, reachability.

Tolerance: prototype inverse kinematics mapped back through the direct kinematics at 1e-12 m.
"""

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

import fpr
from fpr.model.errors import MissionError, SingularityError, WorkspaceError
from fpr.robots.fpr import fpr_workspace_margins
from fpr.robots.prototype import prototype_joints, prototype_workspace_margins
from planners.missions import mission as mission_module
from planners.missions.mission import (
    BUILTIN_MISSIONS,
    Mission,
    builtin_mission_text,
    load_mission,
    mission_from_dict,
    mission_from_toml,
)

S0 = [0.0, 0.0, 5 * np.pi / 4, np.pi / 2]
SQUARE = np.array([S0, [1.0, 0.0, 5 * np.pi / 4, np.pi / 2], [1.0, 1.0, 5 * np.pi / 4, np.pi / 2],
                   [0.0, 1.0, 5 * np.pi / 4, np.pi / 2], S0])
TOUR = np.array([[1.2, -0.45], [1.0, 0.0], [1.3, 0.4], [0.9, 0.9], [0.35, 1.1], [0.5, 0.4], [1.2, -0.1],
                 [1.2, -0.45]])


@pytest.fixture(scope="module")
def robots():
    return {name: fpr.load(name) for name in fpr.ROBOTS}


def base_data():
    """A valid FPR mission as the dictionary of a file: 3 way points, 2 travels."""
    return {
        "robot": "fpr",
        "way_points": [S0, [0.5, 0.2, 5 * np.pi / 4, np.pi / 2], [1.0, 0.0, 4.0, 1.4]],
        "times": [3.0, 2.5],
        "via_points": 1,
    }


def proto(robots, way_points, space="task", arm="down"):
    """A prototype mission through ``way_points`` (1 s per travel)."""
    return Mission(name="p", robot="prototype", way_points=way_points, times=[1.0] * (len(way_points) - 1),
                   space=space, arm=arm)


# ---------------------------------------------------------------------------------------- built-ins
def test_builtin_names_are_the_files():
    folder = Path(mission_module.__file__).parent
    assert sorted(p.stem for p in folder.glob("*.toml")) == sorted(BUILTIN_MISSIONS)


@pytest.mark.parametrize("name", BUILTIN_MISSIONS)
def test_builtin_loads_and_satisfies_margins(name, robots):
    mission = load_mission(name)
    robot = robots[mission.robot]
    assert mission.name == name and mission.source == f"built-in {name}"
    s = mission.positions(robot)
    for i, pose in enumerate(s):  # each way point in its own assembly mode (a crossing ends in the other)
        if mission.robot == "fpr":
            margins = fpr_workspace_margins(pose, robot.link_length, robot.margins)
        elif mission.robot == "prototype":
            margins = prototype_workspace_margins(pose, robot.link_length, robot.margins, mission.arm_of(i))
        else:
            margins = robot.kind.workspace_margins(pose)
        worst = {key: float(np.min(v)) for key, v in margins.items()}
        assert min(worst.values()) >= 0, (i, worst)
    # every field of the file format is documented in the file (as a key or a commented key)
    text = builtin_mission_text(name)
    for key in ("name", "description", "robot", "space", "arm", "way_points", "times", "via_points", "alpha",
                "cross_singularity", "robot_parameters"):
        assert f"# {key} (" in text, key


def test_square_is_the_design_mission(robots):
    m = load_mission("square")
    np.testing.assert_array_equal(m.positions(robots["fpr"]), SQUARE)
    np.testing.assert_array_equal(m.times, [3.0] * 4)
    np.testing.assert_array_equal(m.via_points, [1] * 4)
    assert (m.robot, m.space, m.alpha, dict(m.robot_parameters)) == ("fpr", "task", 0.5, {})


def test_study_is_the_design_mission(robots):
    m = load_mission("study")
    expected = [[0, 0, 3.9270, 1.5708], [1, 1, 3.9270, 1.5708]]
    np.testing.assert_array_equal(m.positions(robots["fpr"]), expected)
    np.testing.assert_array_equal(m.times, [3.0])
    np.testing.assert_array_equal(m.via_points, [1])
    assert m.alpha == 0.5


def test_prototype_tour_maps_back_to_the_drone_positions(robots):
    robot = robots["prototype"]
    m = load_mission("prototype-tour")
    assert (m.robot, m.space, m.arm, m.alpha) == ("prototype", "task", "down", 0.5)
    np.testing.assert_array_equal(m.way_points, TOUR)
    np.testing.assert_array_equal(m.times, [5, 8, 8, 8, 8, 8, 5])
    np.testing.assert_array_equal(m.via_points, [1] * 7)
    xi = m.positions(robot)
    np.testing.assert_allclose(prototype_joints(xi, robot.link_length)[:, 1], TOUR, rtol=0, atol=1e-12)
    assert np.all(xi[:, 1] > 0)  # arm down
    margins = prototype_workspace_margins(xi, robot.link_length, robot.margins)
    least = min(margins, key=lambda k: margins[k].min())
    assert least == "ground_2" and margins[least].min() == pytest.approx(0.0601, abs=1e-4)


def test_arm_up_mirrors_the_elbow(robots):
    robot = robots["prototype"]
    points = [[1.2, 0.1], [1.1, 0.4]]
    down, up = proto(robots, points).positions(robot), proto(robots, points, arm="up").positions(robot)
    assert np.all(up[:, 1] < 0) and np.all(down[:, 1] > 0)
    np.testing.assert_allclose(up[:, 1], -down[:, 1], atol=1e-12)
    np.testing.assert_allclose(prototype_joints(up, robot.link_length)[:, 1], points, atol=1e-12)
    # joint space, arm up: the q2 bounds are mirrored, not taken from the arm-down set
    np.testing.assert_array_equal(proto(robots, up, space="joint", arm="up").positions(robot), up)
    with pytest.raises(SingularityError, match=r"way_points\[1\].*-pi \+ 0.2 <= q2 <= -0.2"):
        proto(robots, [up[0], [up[1, 0], -0.1]], space="joint", arm="up").positions(robot)


def test_docstring_example_is_a_valid_file():
    doc = mission_module.__doc__
    example = doc.split("Full example")[1].split("::\n")[1].split("\nIn Python")[0]
    m = mission_from_toml(textwrap.dedent(example), "example.toml")
    square = load_mission("square").replace(name="example", robot_parameters={"link_length": 1.0})
    assert m == square.replace(description=m.description)
    assert m.name == "example"


# ---------------------------------------------------------------------------------------- round trips
def tricky_mission():
    return Mission(
        name="tricky \"name\"", robot="fpr",
        way_points=[S0, [0.1 + 0.2, 1e-300, 4.0, 1.2], [-0.0, 1 / 3, 2 * np.pi - 0.3, np.pi / 7]],
        times=[0.1, 123456.789], via_points=[0, 3], alpha=1 / 3, space="joint",
        description="line 1\nline 2 \\ \t \"quoted\" é ∞ \x01 \x7f",
        robot_parameters={"link_length": 1.0, "drone_mass": 1.25},
    )


@pytest.mark.parametrize("mission", [load_mission(n) for n in BUILTIN_MISSIONS] + [tricky_mission()],
                         ids=list(BUILTIN_MISSIONS) + ["tricky"])
def test_toml_and_dict_round_trips(mission):
    back = mission_from_toml(mission.to_toml())
    assert back == mission
    for key in ("way_points", "times", "via_points"):
        a, b = getattr(back, key), getattr(mission, key)
        assert a.dtype == b.dtype and np.array_equal(a, b), key
    for key in ("name", "robot", "alpha", "space", "arm", "description"):
        assert getattr(back, key) == getattr(mission, key), key
    assert dict(back.robot_parameters) == dict(mission.robot_parameters)
    assert mission_from_dict(json.loads(json.dumps(mission.to_dict()))) == mission


def test_equality_sees_every_field():
    m = tricky_mission()
    assert m == tricky_mission()
    nudged = m.way_points.copy()
    nudged[1, 0] = np.nextafter(nudged[1, 0], 1.0)
    for change in (dict(way_points=nudged), dict(alpha=0.3), dict(times=[0.1, 1.0]), dict(via_points=[0, 2]),
                   dict(description=""), dict(name="other"), dict(space="task"), dict(arm="up"),
                   dict(robot_parameters={"link_length": 1.0})):
        assert m.replace(**change) != m, change
    assert m.replace(source="elsewhere") == m  # where it came from is not part of the mission


# ---------------------------------------------------------------------------------------- validation
def _set(key, value):
    def change(d):
        d[key] = value
    return change


def _set_item(key, index, value):
    def change(d):
        d[key] = [list(x) if isinstance(x, list) else x for x in d[key]]
        d[key][index] = value
    return change


def _del(key):
    def change(d):
        del d[key]
    return change


MALFORMED = [
    ("negative time", _set_item("times", 1, -2.0), "times[1]"),
    ("zero time", _set_item("times", 0, 0.0), "times[0]"),
    ("infinite time", _set_item("times", 1, float("inf")), "times[1]"),
    ("time as text", _set_item("times", 0, "3 s"), "times[0]"),
    ("times a scalar", _set("times", 3.0), "times"),
    ("wrong times count", _set("times", [3.0]), "times"),
    ("NaN way point", _set_item("way_points", 1, [0.5, float("nan"), 3.9, 1.5]), "way_points[1]"),
    ("wrong way-point length", _set_item("way_points", 2, [1.0, 0.0, 4.0]), "way_points[2]"),
    ("way point entry as text", _set_item("way_points", 0, [0.0, "0", 3.9, 1.5]), "way_points[0]"),
    ("bool in a way point", _set_item("way_points", 0, [0.0, True, 3.9, 1.5]), "way_points[0]"),
    ("one way point", _set("way_points", [S0]), "way_points"),
    ("alpha 1.5", _set("alpha", 1.5), "alpha"),
    ("alpha negative", _set("alpha", -0.1), "alpha"),
    ("alpha a bool", _set("alpha", True), "alpha"),
    ("via_points -1", _set("via_points", -1), "via_points"),
    ("via_points 1.5", _set("via_points", 1.5), "via_points"),
    ("via_points 1.0", _set("via_points", 1.0), "via_points"),
    ("via_points true", _set("via_points", True), "via_points"),
    ("via_points entry -1", _set("via_points", [1, -1]), "via_points[1]"),
    ("via_points count", _set("via_points", [1, 1, 1]), "via_points"),
    ("unknown key", _set("speed", 2.0), "speed"),
    ("source is not a file key", _set("source", "x"), "source"),
    ("missing times", _del("times"), "times"),
    ("missing robot", _del("robot"), "robot"),
    ("unknown robot", _set("robot", "hexapod"), "robot"),
    ("bad arm", _set("arm", "sideways"), "arm"),
    ("bad space", _set("space", "cartesian"), "space"),
    ("name not a string", _set("name", 3), "name"),
    ("unknown robot parameter", _set("robot_parameters", {"foo": 1.0}), "robot_parameters.foo"),
    ("negative robot parameter", _set("robot_parameters", {"link_length": -1.0}),
     "robot_parameters.link_length"),
    ("robot parameters not a table", _set("robot_parameters", 1.0), "robot_parameters"),
]


def test_base_data_is_valid(robots):
    m = mission_from_dict(base_data())
    assert m.positions(robots["fpr"]).shape == (3, 4) and m.name == "unnamed"


@pytest.mark.parametrize("change, field", [(c, f) for _, c, f in MALFORMED], ids=[i for i, _, _ in MALFORMED])
def test_malformed_input_names_the_field(change, field):
    data = base_data()
    change(data)
    with pytest.raises(MissionError) as info:
        mission_from_dict(data, source="bad.toml")
    assert info.value.field == field
    assert info.value.source == "bad.toml" and str(info.value).startswith(f"bad.toml: field {field!r}")


def test_unknown_key_lists_the_known_ones():
    data = base_data()
    data["time"] = [3.0, 3.0]
    with pytest.raises(MissionError, match="did you mean 'times'.*robot, space, arm, way_points, times"):
        mission_from_dict(data)


def test_file_errors_name_the_field_and_the_file(tmp_path):
    path = tmp_path / "my_tour.toml"
    text = builtin_mission_text("prototype-tour")
    path.write_text(text, encoding="utf-8")
    assert load_mission(path).name == "my_tour"  # the name defaults to the file stem
    assert load_mission(str(path)).source == str(path)
    path.write_text(text.replace("times = [5.0, 8.0, 8.0,", "times = [5.0, 8.0, -8.0,"), encoding="utf-8")
    with pytest.raises(MissionError) as info:
        load_mission(path)
    assert info.value.field == "times[2]" and str(path) in str(info.value)
    path.write_text(text.replace("[0.9, 0.9],", "[0.9, nan],"), encoding="utf-8")
    with pytest.raises(MissionError) as info:
        load_mission(path)
    assert info.value.field == "way_points[3]"


def test_toml_syntax_error_gives_the_line(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text('robot = "fpr"\ntimes = [3.0]\nway_points = [[0, 0, 3.9, 1.5] [1, 1, 3.9, 1.5]]\n',
                    encoding="utf-8")
    with pytest.raises(MissionError) as info:
        load_mission(path)
    assert info.value.field == "<toml>" and "line 3" in str(info.value)
    with pytest.raises(MissionError, match="line 2"):
        mission_from_toml('robot = "fpr"\nalpha =')


def test_unknown_mission_lists_the_builtins(tmp_path):
    for missing in ("sqare", tmp_path / "nothing.toml"):
        with pytest.raises(MissionError, match="square, study, prototype-tour") as info:
            load_mission(missing)
        assert info.value.field == "<file>"


def test_arrays_are_read_only():
    m = load_mission("square")
    for key in ("way_points", "times", "via_points"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(m, key)[0] = 0
    with pytest.raises(TypeError):
        m.robot_parameters["link_length"] = 2.0


def test_replace_validates_and_broadcasts():
    m = load_mission("square")
    r = m.replace(alpha=0.3, via_points=2, times=[1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(r.via_points, [2, 2, 2, 2])
    np.testing.assert_array_equal(r.times, [1, 2, 3, 4])
    np.testing.assert_array_equal(m.replace(way_points=SQUARE[:3], times=[1.0, 1.0]).via_points, [1, 1])
    with pytest.raises(MissionError) as info:  # non-uniform via points must be given again
        r.replace(via_points=[1, 2, 1, 2]).replace(way_points=SQUARE[:3], times=[1.0, 1.0])
    assert info.value.field == "via_points"
    assert r.alpha == 0.3 and r.duration == 10.0 and r.source == m.source
    assert m.alpha == 0.5 and m.duration == 12.0  # the original is unchanged
    with pytest.raises(MissionError) as info:
        m.replace(times=[1.0, 2.0, 0.0, 4.0])
    assert info.value.field == "times[2]"
    with pytest.raises(MissionError, match="did you mean 'alpha'") as info:
        m.replace(alpah=0.3)
    assert info.value.field == "alpah"


def test_joint_space_arm_must_match_the_sign_of_q2(robots):
    with pytest.raises(MissionError) as info:
        proto(robots, [[0.3, 1.2], [0.2, -1.0], [0.3, 1.2]], space="joint")
    assert info.value.field == "way_points[1]"
    with pytest.raises(MissionError) as info:
        proto(robots, [[0.3, -1.2], [0.2, -1.0]], space="joint")
    assert info.value.field == "arm"


# ---------------------------------------------------------------------------------------- reachability
def test_unreachable_prototype_way_point(robots):
    with pytest.raises(WorkspaceError, match=r"way_points\[1\].*3 m away"):
        proto(robots, [[1.0, 0.5], [3.0, 0.0], [1.0, 0.5]]).positions(robots["prototype"])


def test_way_points_on_a_singularity(robots):
    square = load_mission("square")
    on_singularity = [S0, [0.5, 0.5, 5 * np.pi / 4, 0.05]]
    with pytest.raises(SingularityError, match=r"way_points\[1\].*q21") as info:
        square.replace(way_points=on_singularity, times=[3.0]).positions(robots["fpr"])
    assert info.value.margin == pytest.approx(0.05)
    with pytest.raises(SingularityError, match=r"way_points\[1\].*q2") as info:
        proto(robots, [[0.3, 1.2], [0.3, 0.0]], space="joint").positions(robots["prototype"])
    assert info.value.margin == 0.0
    two_l = 2 * robots["prototype"].link_length
    with pytest.raises(SingularityError, match=r"way_points\[1\].*aligned") as info:
        proto(robots, [[1.0, 0.5], [two_l, 0.0]]).positions(robots["prototype"])
    assert info.value.margin == 0.0


def test_fpr_way_point_below_the_ground(robots):
    below = [S0, [0.0, -1.5, 5 * np.pi / 4, np.pi / 2], S0]
    with pytest.raises(WorkspaceError, match=r"way_points\[1\].*ground"):
        load_mission("square").replace(way_points=below, times=[3.0, 3.0]).positions(robots["fpr"])


def test_positions_needs_the_mission_robot(robots):
    m = load_mission("square")
    with pytest.raises(MissionError) as info:
        m.positions(robots["prototype"])
    assert info.value.field == "robot"
    with pytest.raises(MissionError) as info:
        m.replace(robot_parameters={"link_length": 1.0}).positions(robots["fpr"])
    assert info.value.field == "robot_parameters.link_length"


# ---------------------------------------------------------------------------------------- robot parameters
def test_robot_parameters_reach_the_model():
    m = load_mission("prototype-tour")
    assert m.load_robot().link_length == pytest.approx(0.75, abs=1e-12)
    longer = m.replace(robot_parameters={"link_length": 1.0})
    robot = longer.load_robot()
    assert robot.link_length == pytest.approx(1.0, abs=1e-12)
    far = longer.replace(way_points=[[1.6, 0.3], [1.3, 0.8]], times=[3.0])  # out of reach with L = 0.75 m
    xi = far.positions(robot)
    np.testing.assert_allclose(prototype_joints(xi, 1.0)[:, 1], far.way_points, atol=1e-12)
    with pytest.raises(WorkspaceError, match=r"way_points\[0\]"):
        far.replace(robot_parameters={}).positions()


def test_bad_override_key_from_load_robot(monkeypatch):
    """A key that passed validation but that fpr.load rejects is reported on its field."""
    with monkeypatch.context() as patch:
        patch.setattr(mission_module.description, "xacro_arguments", lambda xacro=None: ("foo", "link_length"))
        m = load_mission("square").replace(robot_parameters={"foo": 1.0})
    with pytest.raises(MissionError) as info:
        m.load_robot()
    assert info.value.field == "robot_parameters.foo" and "foo" in info.value.reason
