"""Mission events (planners/missions/events.py): parsing, validation with the field named, the TOML round trip."""

import numpy as np
import pytest

from fpr.model.errors import MissionError, WorkspaceError
from planners.missions.events import GustEvent, MoveEvent, gust_force, moved_positions
from planners.missions.mission import load_mission, mission_from_toml

S0 = [0.0, 0.0, 3.9269908169872414, 1.5707963267948966]


def _square(events):
    return load_mission("square").replace(events=events)


def test_builtin_missions_carry_their_events():
    moving = load_mission("moving-target")
    assert moving.events == (MoveEvent(4.0, 2, (1.2, 0.8, S0[2], S0[3])),)
    gust = load_mission("gust")
    assert len(gust.events) == 1 and gust.events[0].kind == "gust" and gust.events[0].body == "end_effector"
    assert gust.events[0].force[1] != 0.0 and gust.events[0].force[0] == gust.events[0].force[2] == 0.0


def test_toml_round_trip_keeps_events_and_sorts_them_by_time():
    mission = _square(
        [
            {"at": 5.0, "kind": "gust", "force": [0.0, 3.0, 0.0], "duration": 0.2, "body": "drone_2"},
            {"at": 1.0, "kind": "move", "way_point": 1, "to": [0.9, 0.1, S0[2], S0[3]]},
        ]
    )
    assert [e.kind for e in mission.events] == ["move", "gust"]  # sorted by at
    again = mission_from_toml(mission.to_toml())
    assert again == mission and again.events == mission.events
    assert "[[events]]" in mission.to_toml()
    # a mission without events writes the same text as before events existed
    assert (
        "events" not in load_mission("square").to_toml() and "events" not in load_mission("square").to_dict()
    )


@pytest.mark.parametrize(
    "event, field, words",
    [
        ({"kind": "move", "way_point": 1, "to": S0}, "events[0].at", "missing"),
        ({"at": 1.0, "kind": "jump"}, "events[0].kind", "'move', 'gust'"),
        ({"at": -1.0, "kind": "move", "way_point": 1, "to": S0}, "events[0].at", "[0, 12)"),
        ({"at": 12.0, "kind": "move", "way_point": 1, "to": S0}, "events[0].at", "[0, 12)"),
        (
            {"at": float("nan"), "kind": "gust", "force": [0, 1, 0], "duration": 1.0},
            "events[0].at",
            "[0, 12)",
        ),
        ({"at": 1.0, "kind": "move", "way_point": 0, "to": S0}, "events[0].way_point", "1..4"),
        ({"at": 1.0, "kind": "move", "way_point": 5, "to": S0}, "events[0].way_point", "1..4"),
        ({"at": 1.0, "kind": "move", "way_point": True, "to": S0}, "events[0].way_point", "1..4"),
        ({"at": 4.0, "kind": "move", "way_point": 1, "to": S0}, "events[0].at", "reached at 3 s"),
        ({"at": 1.0, "kind": "move", "way_point": 1, "to": [1.0, 0.0]}, "events[0].to", "4 numbers"),
        ({"at": 1.0, "kind": "move", "way_point": 1, "to": [1.0, 0.0, "a", 1.0]}, "events[0].to", "entry 2"),
        (
            {"at": 1.0, "kind": "move", "way_point": 1, "to": S0, "force": [0, 0, 0]},
            "events[0].force",
            "unknown key",
        ),
        ({"at": 1.0, "kind": "gust", "force": [0, 1], "duration": 1.0}, "events[0].force", "3 numbers"),
        (
            {"at": 1.0, "kind": "gust", "force": [0, float("inf"), 0], "duration": 1.0},
            "events[0].force",
            "finite",
        ),
        ({"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 0.0}, "events[0].duration", "> 0"),
        ({"at": 1.0, "kind": "gust", "force": [0, 1, 0]}, "events[0].duration", "missing"),
        (
            {"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 1.0, "body": "drone_0"},
            "events[0].body",
            '"drone_1", "drone_2"',
        ),
        (
            {"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 1.0, "body": "wing"},
            "events[0].body",
            '"drone_1", "drone_2"',
        ),
        (  # the FPR has two drones: a gust on a third one would be silently dropped
            {"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 1.0, "body": "drone_3"},
            "events[0].body",
            "has 2 drone(s)",
        ),
        ({"at": 1.0, "kind": "gust", "force": [0, 1e300, 0], "duration": 1.0}, "events[0].force", "within +-1000"),
        ("gust", "events[0]", "table"),
        (
            {"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 1.0, "rise": -0.1},
            "events[0].rise",
            ">= 0",
        ),
        (
            {"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 1.0, "rise": 0.6},
            "events[0].rise",
            "half the duration",
        ),
        (
            {"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 1.0, "rise": float("nan")},
            "events[0].rise",
            "onset",
        ),
        ({"at": 1.0, "kind": "gust", "force": [0, 1, 0], "duration": 1.0, "rise": True}, "events[0].rise", "onset"),
        ({"at": 1.0, "kind": "move", "way_point": 1, "to": S0, "rise": 0.5}, "events[0].rise", "unknown key"),
    ],
)
def test_every_field_is_validated_and_named(event, field, words):
    with pytest.raises(MissionError) as info:
        _square([event])
    assert info.value.field == field
    assert words in info.value.reason


def test_events_must_be_a_list_of_tables():
    text = load_mission("square").to_toml().replace("[robot_parameters]", "events = 3\n[robot_parameters]")
    with pytest.raises(MissionError) as info:
        mission_from_toml(text)
    assert info.value.field == "events"


def test_moved_positions_are_checked_against_the_workspace():
    robot = load_mission("square").load_robot()
    mission = _square([{"at": 1.0, "kind": "move", "way_point": 2, "to": [1.0, 0.5, 3.0, S0[3]]}])
    with pytest.raises(WorkspaceError, match=r"events\[0\]\.to"):  # phi below pi + m_ga
        moved_positions(mission, robot)
    fine = _square([{"at": 1.0, "kind": "move", "way_point": 2, "to": [1.2, 0.8, S0[2], S0[3]]}])
    np.testing.assert_array_equal(moved_positions(fine, robot)[0], [1.2, 0.8, S0[2], S0[3]])


def test_gust_force_is_on_only_during_its_window_and_adds_up():
    events = (
        GustEvent(1.0, (0.0, 2.0, 0.0), 0.5),
        GustEvent(1.2, (0.0, 1.0, 0.0), 0.1),
        GustEvent(1.0, (1.0, 0.0, 0.0), 0.5, "drone_2"),
    )
    assert gust_force(events, 0.999, 2) == (None, None)
    tip, drones = gust_force(events, 1.25, 2)
    np.testing.assert_array_equal(tip, [0.0, 3.0, 0.0])
    np.testing.assert_array_equal(drones, [[0, 0, 0], [1.0, 0, 0]])
    assert gust_force(events, 1.5, 2) == (None, None)  # [at, at + duration)


def test_a_gust_with_a_rise_builds_up_smoothly_and_its_rates_are_those_of_its_value():
    """rise > 0: 0 at the start, the full force after ``rise``, back to 0 at the end; C2 (rates checked by
    finite differences of the value), close to the 1 - cosine discrete gust; rise 0 keeps the step.
    """
    gust = GustEvent(1.0, (0.0, -8.0, 0.0), 3.0, rise=0.8)
    t = np.linspace(0.5, 4.5, 40001)
    value, rate, curvature = gust.strength(t)
    assert value[t < 1.0].max() == 0.0 and value[t >= 4.0].max() == 0.0
    np.testing.assert_array_equal(value[(t >= 1.8) & (t <= 3.2)], 1.0)
    h = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(value, h), rate, atol=1e-3)
    np.testing.assert_allclose(np.gradient(rate, h), curvature, atol=2e-2)
    onset = (t >= 1.0) & (t <= 1.8)
    cosine = 0.5 * (1.0 - np.cos(np.pi * (t[onset] - 1.0) / 0.8))
    assert np.abs(value[onset] - cosine).max() < 0.045  # 0.044: the ramp is steeper mid-way
    tip, _ = gust_force((gust,), 1.4, 2)  # halfway up: half the force
    np.testing.assert_allclose(tip, [0.0, -4.0, 0.0], atol=1e-12)
    step = GustEvent(1.0, (0.0, -8.0, 0.0), 3.0)
    np.testing.assert_array_equal(step.strength(np.array([0.99, 1.0, 3.99, 4.0]))[0], [0, 1, 1, 0])
    # round trip: the rise is written when it is not 0, and a step gust is written as before
    mission = _square([gust.to_dict(), step.to_dict()])
    assert mission_from_toml(mission.to_toml()).events == mission.events
    assert "rise" not in step.to_dict() and gust.to_dict()["rise"] == 0.8
