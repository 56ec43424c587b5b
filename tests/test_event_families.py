"""Event families for campaigns (fpr/robustness/events.py), the static gust-holding check
(fpr/robustness/holding.py) against the closed-chain plant, one run of each family (fpr/robustness/outcomes.py)
and the replanner's wind estimate from the controller's observer (fpr/sim/replanning.py).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import tomllib

import fpr
from fpr.model.errors import CampaignError
from fpr.robustness.campaign_file import campaign_from_dict, campaign_to_toml
from fpr.robustness.events import GustFamily, MoveFamily, event_generator, family
from fpr.robustness.holding import hold_check, static_hold
from fpr.robustness.outcomes import EventSetup, Flight, fly
from fpr.robustness.spec import Campaign
from fpr.robustness.summary import event_summary
from fpr.sim.closed_loop import SimulationSettings
from fpr.sim.replanning import ForcedPlant, InFlight, TriggerSettings
from planners.missions.events import GustEvent, moved_positions
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.replanning.latency import LatencyModel
from planners.replanning.replanner import Replanner, ReplanOptions


@pytest.mark.parametrize("name", ["square", "prototype-tour"])
def test_move_events_are_seeded_within_reach_and_warned(name):
    """Each draw: a way point after the start, moved by a distance in the family's range, at least ``warning``
    before the robot gets there and after it left the previous one, its target within the workspace; the same
    (seed, index) gives the same event, another index another.
    """
    mission = load_mission(name)
    robot = mission.load_robot()
    family_ = MoveFamily()
    ends = np.concatenate([[0.0], np.cumsum(mission.times)])
    events = [family_.draw(mission, robot, event_generator(3, i)) for i in range(30)]
    assert events[4] == family_.draw(mission, robot, event_generator(3, 4))
    assert len(set(events)) == 30
    for event in events:
        j = event.way_point
        assert 1 <= j < len(ends)
        assert ends[j - 1] <= event.at <= ends[j] - family_.warning
        moved = np.linalg.norm(np.array(event.to[:2]) - mission.way_points[j][:2])
        assert family_.distance[0] - 1e-6 <= moved <= family_.distance[1] + 1e-6
        np.testing.assert_array_equal(event.to[2:], mission.way_points[j][2:])
        moved_positions(mission, robot, (event,))  # within reach: raises otherwise
    assert {e.way_point for e in events} == set(range(1, len(ends)))


def test_gust_draws_cover_the_family():
    mission = load_mission("square")
    robot = mission.load_robot()
    gusts = [GustFamily().draw(mission, robot, event_generator(0, i)) for i in range(60)]
    for gust in gusts:
        assert gust.force[0] == 0.0 and np.hypot(*gust.force[1:]) <= 8.0 + 1e-6
        assert 0.0 <= gust.rise <= min(1.0, gust.duration / 2) + 1e-9 and 0.0 <= gust.at < mission.duration
        mission.replace(events=(gust,))  # a valid event of the mission
    assert {g.body for g in gusts} == {"end_effector", "drone_1", "drone_2"}
    angles = np.arctan2([g.force[2] for g in gusts], [g.force[1] for g in gusts])
    assert np.ptp(angles) > 5.0  # all around the plane
    with pytest.raises(CampaignError, match="bodies"):
        GustFamily(bodies="wings")
    with pytest.raises(CampaignError, match="unknown event family"):
        family("storm")


@pytest.mark.parametrize("name, body, force", [("fpr", "end_effector", (0.0, 6.0, 3.0)),
                                               ("fpr", "drone_2", (0.0, -5.0, -4.0)),
                                               ("prototype", "end_effector", (0.0, 4.0, 5.0)),
                                               ("prototype", "drone_1", (0.0, -7.0, 0.0))])
def test_a_static_hold_holds_the_closed_chain_plant_still(name, body, force):
    """The rolls, thrusts and roll torques of static_hold, made by its rotor speeds, keep the plant (the
    closed-chain constraint dynamics, not the minimal model the check solves) at rest under the gust: its
    accelerations over a first step are those of round-off.
    """
    robot = fpr.load(name)
    s = np.array(robot.kind.reference_chain) + (0.05 if name == "fpr" else 0.1)
    hold = static_hold(robot, s, body, force)
    assert hold.residual < 1e-9
    q = np.zeros(robot.nq)
    q[robot.indices(robot.layout.chain)] = s
    q[robot.indices(robot.layout.rolls)] = hold.roll
    speeds = np.sqrt(hold.speeds_squared)
    plant = ForcedPlant.with_events((GustEvent(0.0, force, 10.0, body),), robot, q, np.zeros(robot.nq), speeds)
    dt = 1e-3
    plant.step(speeds, dt)
    _, v, _, _ = plant.observe()
    assert np.abs(v).max() / dt < 1e-6, np.abs(v).max() / dt
    # and the point-drone model's thrust vectors at rest are its thrusts along its rolls
    assert np.all(hold.thrust > 0)


def test_hold_check_counts_a_gust_no_rotor_can_hold_apart():
    mission = load_mission("square")
    robot = mission.load_robot()
    small = hold_check(robot, mission, GustEvent(2.0, (0.0, 3.0, 0.0), 5.0, "drone_1"))
    huge = hold_check(robot, mission, GustEvent(2.0, (0.0, 0.0, -40.0), 5.0))
    assert small.holdable and small.margin > 0 and small.line().startswith("holdable")
    assert not huge.holdable and huge.margin < 0 and huge.line().startswith("not holdable")
    assert huge.samples == 2  # way points 1 (3 s) and 2 (6 s): those reached while it blows
    # the built-in gust mission's 6 N: holdable where the robot must be
    gust = load_mission("gust")
    assert hold_check(robot, gust, gust.events[0]).holdable


def _flight(mission, family_name, result, **setup):
    generator = MoveFamily() if family_name == "move" else GustFamily()
    robot = result.robot
    event_setup = EventSetup(family_name, generator, 7, latency=LatencyModel((0.002, 0.001, 2e-4, 0.0, 0.0)),
                             **setup)
    return Flight(robot.name, (), tuple(robot.layout.chain), result.trajectory, 0.5, None, mission,
                  result.report.constraints, event_setup)


def test_a_move_run_passes_the_moved_way_point_and_its_row_says_so():
    mission = load_mission("square")
    result = plan(mission, "two-step")
    flight = _flight(mission, "move", result, replan=True)
    row = fly(flight, 0, {}, 0)
    assert row["error"] == "" and row["success"] and row["miss"] == ""
    assert row["pass_distance_m"] <= 0.02 and row["replans_used"] >= 1 and row["executed_violates"] == ""
    assert set(flight.columns) <= set(row) and len(row["replan_wall_s"]) == row["replans"]
    # without the replanner the robot flies to where the way point was: a miss that says why
    flown = dataclasses.replace(flight, setup=dataclasses.replace(flight.setup, replan=False))
    missed = fly(flown, 0, {}, 0)
    assert not missed["success"] and missed["miss"].startswith("not replanned")
    summary = event_summary([row, missed], "move")
    assert summary["with_observer"]["successes"] == 1 and summary["misses"][0]["index"] == 0


def test_a_gust_run_has_its_event_its_verdict_and_the_run_without_the_observer():
    mission = load_mission("square")
    result = plan(mission, "two-step")
    flight = _flight(mission, "gust", result, without_observer=True)
    row = fly(flight, 1, {}, 0)
    gust = flight.setup.event(mission, result.robot, 1)
    assert row["gust_body"] == gust.body and row["gust_force_n"] == pytest.approx(np.hypot(*gust.force[1:]))
    assert row["holdable"] is True and row["error"] == ""
    assert isinstance(row["no_observer_success"], bool) and row["no_observer_worst_error"] > 0
    assert row["success"] == (row["miss"] == "")
    summary = event_summary([row], "gust", without_observer=True)
    assert summary["with_observer"]["runs"] == 1 and "without_observer" in summary


def test_a_campaign_file_with_an_event_family_round_trips():
    document = {"mission": "square", "runs": 4, "events": "gust", "without_observer": True,
                "max_saturation": 0.02, "event_options": {"force": [0.0, 4.0], "bodies": "drones"}}
    campaign = campaign_from_dict(document)
    assert campaign.events == "gust" and campaign.event_family().force == (0.0, 4.0)
    again = campaign_from_dict(tomllib.loads(campaign_to_toml(campaign)))
    assert again == campaign and again.key("m") == campaign.key("m")
    assert Campaign().key("m") != campaign.key("m")
    with pytest.raises(CampaignError, match="option"):
        campaign_from_dict({**document, "event_options": {"strength": 3}})
    with pytest.raises(CampaignError, match="max_saturation"):
        campaign_from_dict({**document, "max_saturation": 2.0})


def test_the_campaign_options_name_the_families_and_reach_the_campaign(tmp_path):
    """The light parser's --events choices (written there so that --help imports nothing heavy) are the
    families; --events, --replan and --without-observer reach the campaign over its file's fields.
    """
    from fpr.cli.campaign import _campaign
    from fpr.cli.campaign_options import EVENT_FAMILIES, parser
    from fpr.robustness.events import FAMILIES

    assert EVENT_FAMILIES == FAMILIES
    file = tmp_path / "c.toml"
    file.write_text('events = "move"\nreplan = false\n[event_options]\ndistance = [0.05, 0.1]\n', encoding="utf-8")
    campaign = _campaign(parser().parse_args(["--campaign", str(file), "--replan", "--without-observer"]))
    assert campaign.events == "move" and campaign.replan and campaign.without_observer
    assert campaign.event_options == {"distance": [0.05, 0.1]}
    assert _campaign(parser().parse_args(["--events", "gust"])).events == "gust"
    assert not _campaign(parser().parse_args([])).replan


def test_the_observers_estimate_is_assumed_after_its_delay_and_again_when_it_moves():
    """With the controller's observer the replanner plans against its estimate (forces on the task point and
    the drones) once it has held ``observed_delay``, and again when it has moved by more than the threshold
    for as long; none of it while the estimate stays under the threshold.
    """
    mission = load_mission("gust")
    result = plan(mission, "two-step")
    robot = result.robot
    chain = [robot.index[c] for c in robot.layout.chain]
    replanner = Replanner(result, ReplanOptions(deadline=0.3, latency=LatencyModel((0.0,) * 5)))
    triggers = TriggerSettings(known_gusts=False, estimate_wind=True, tracking_bound=None)
    hooks = InFlight(mission, replanner, triggers, SimulationSettings().controller, chain, robot)
    assert hooks.observed and hooks.estimator is None

    def forces(t):
        task = np.array([0.0, -0.5 if t < 2.0 else (-4.0 if t < 3.0 else -6.0), 0.0])
        return task, np.zeros((robot.n_drones, 3))

    hooks.attach(SimpleNamespace(estimated_forces=lambda: forces(hooks._now)))
    for t in np.arange(1.5, 4.0, 0.002):
        hooks._now = t
        reference = replanner.trajectory.evaluate(np.array([t]), 4)[:, 0]
        q = robot.configuration(**dict(zip(robot.layout.chain, reference[0], strict=True)))
        hooks.after_tick(float(t), q, np.zeros(robot.nq), reference)
    records = [(round(r.time, 3), r.trigger.split(":")[0]) for r in replanner.replans]
    delay = triggers.observed_delay
    assert (round(2.0 + delay, 3), "wind estimated") in records, records
    assert (round(3.0 + delay, 3), "wind estimate changed") in records, records
    assert all(t >= 2.0 + delay - 1e-9 for t, _ in records)
    assert replanner.assumed[0].force == (0.0, -6.0, 0.0) and replanner.assumed[0].body == "end_effector"


def test_a_gust_whose_rise_is_half_its_duration_is_drawn_within_it():
    """Draws whose rise was cut to half the duration (runs 11 and 34 of seed 5): rounded, the rise stays within
    half the rounded duration, and the mission takes the gust (it refused a rise 1e-6 s over).
    """
    mission = load_mission("square")
    robot = mission.load_robot()
    for index in (11, 34):
        gust = GustFamily().draw(mission, robot, event_generator(5, index))
        assert gust.rise <= gust.duration / 2 and gust.rise == pytest.approx(gust.duration / 2, abs=1e-6)
        mission.replace(events=(gust,))
