"""What a robot kind says about its axes, its drones' attitude, its out-of-plane coordinates and its constraints,
and that the generic code reads it from the kind instead of from coordinate names.
"""

from __future__ import annotations

import ast
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import fpr
import fpr.robots
from fpr.model.errors import RobotDefinitionError
from fpr.model.robot import Robot
from fpr.robots.fpr import Fpr
from planners.problem.motion import CONSTRAINT_KINDS, constraint_kind, workspace_kinds

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module", params=["fpr", "prototype"])
def robot(request):
    return fpr.load(request.param)


def test_the_planar_kinds_give_the_world_y_z_axes_and_their_arrays_follow(robot):
    kind = robot.kind
    assert kind.force_axes == ("y", "z")
    s = np.array(kind.reference_chain)
    n_d, k = robot.n_drones, len(kind.force_axes)
    assert kind.drone_joints(s).shape == (n_d, k)
    assert kind.drone_joint_velocities(s, np.ones_like(s)).shape == (n_d, k)
    assert kind.chain_jacobian(s).shape == (n_d * k, s.size)
    b = robot.planar("point").inverse_dynamics(s, np.zeros_like(s), np.zeros_like(s))
    force = kind.outer_loop_forces(s, b, kind.chain_jacobian(s), None, 0.1)
    assert force.shape == (n_d, k)
    assert kind.fixed_point is None or len(kind.fixed_point) == k


def test_drone_attitude_names_each_drones_roll_and_rolls_keep_their_names_and_order(robot):
    layout = robot.layout
    expected = {"fpr": (("phi1",), ("phi2",)), "prototype": (("phi1",),)}[robot.name]
    assert layout.drone_attitude == expected
    assert len(layout.drone_attitude) == robot.n_drones
    # the former rule (attitude coordinates named phi...) gives the same rolls, in the same order
    assert layout.rolls == tuple(c for c in layout.attitude if c.startswith("phi"))
    assert set(layout.rolls) <= set(layout.attitude)


def test_a_layout_whose_drone_attitude_does_not_fit_is_refused(robot):
    from dataclasses import replace

    kind = type(robot.kind)
    too_few = type("TooFew", (kind,), {"layout": replace(kind.layout, drone_attitude=())})
    with pytest.raises(RobotDefinitionError, match="drone_attitude"):
        Robot(too_few, robot.urdf, robot.parameters)
    stray = type("Stray", (kind,), {"layout": replace(kind.layout, drone_attitude=(("q9",),) * robot.n_drones)})
    with pytest.raises(RobotDefinitionError, match="q9"):
        Robot(stray, robot.urdf, robot.parameters)


def test_out_of_plane_coordinates_are_the_kinds(robot):
    expected = {"fpr": ("x", "psi", "theta"), "prototype": ("psi", "theta")}[robot.name]
    kind = robot.kind
    assert kind.out_of_plane == expected
    assert set(kind.out_of_plane) <= set(robot.layout.coordinates)
    assert not set(kind.out_of_plane) & set(robot.layout.chain + robot.layout.rolls)


def test_ground_height_is_required_of_a_kind_whose_drones_hang_on_no_link(robot):
    assert robot.kind.ground_height == -robot.link_length
    no_link = Fpr.__new__(Fpr)
    no_link.robot = SimpleNamespace(link_length=0.0)
    with pytest.raises(RobotDefinitionError, match="ground_height"):
        _ = no_link.ground_height


def test_constraint_kinds_are_the_generic_ones_and_the_registered_robots():
    assert {"rotor_speed_low", "rotor_speed_high", "thrust_low"} <= set(CONSTRAINT_KINDS)
    for name in fpr.robots.names():
        kind = fpr.robots.get(name)
        for key, entry in kind.constraint_kinds.items():
            assert CONSTRAINT_KINDS[key][0] == entry[0]
        assert set(kind.attitude_kinds) <= set(kind.constraint_kinds)
    assert workspace_kinds() == {"ground", "fixed_point", "phi", "q21", "q1", "q2", "crossing",
                                 "leg", "distance", "chart", "singular"}  # the last four: the spatial FPR's
    assert constraint_kind("q21_low") == "q21" and constraint_kind("q2_high") == "q2"


def test_every_margin_a_robot_gives_has_a_kind_it_registered(robot):
    names = robot.kind.workspace_margins(np.array(robot.kind.reference_chain))
    for name in names:
        assert constraint_kind(name) in robot.kind.constraint_kinds
        assert constraint_kind(name) in workspace_kinds()


def test_a_registered_kind_adds_its_constraint_kinds_and_a_unit_clash_is_refused():
    tilted = type("Tilted", (Fpr,), {"name": "tilted_test_kind",
                                     "constraint_kinds": {**Fpr.constraint_kinds,
                                                          "sway": ("rad", "drone sway")},
                                     "attitude_kinds": ("roll", "sway")})
    assert "sway" not in CONSTRAINT_KINDS
    with pytest.raises(StopIteration):
        constraint_kind("sway_3")  # (an answer constraint_kind remembers only while the registry stays)
    fpr.robots.register(tilted)
    try:
        assert CONSTRAINT_KINDS["sway"][0] == "rad"
        assert constraint_kind("sway_3") == "sway"
        assert "sway" not in workspace_kinds()
    finally:
        fpr.robots.unregister(tilted.name)
    assert "sway" not in CONSTRAINT_KINDS
    assert constraint_kind("ground_1") == "ground"
    clash = type("Clash", (Fpr,), {"name": "clash_test_kind", "constraint_kinds": {"ground": ("rad", "?")}})
    fpr.robots.register(clash)
    try:
        with pytest.raises(RobotDefinitionError, match="ground"):
            CONSTRAINT_KINDS["ground"]
    finally:
        fpr.robots.unregister(clash.name)


def _string_tuples(path: Path) -> set[tuple[str, ...]]:
    """The tuples of string literals in a module's source."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Tuple) and node.elts and all(
                isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts):
            found.add(tuple(e.value for e in node.elts))
    return found


@pytest.mark.parametrize("module", ["fpr/sim/closed_loop.py", "fpr/views/figures/simulation.py"])
def test_generic_code_reads_out_of_plane_coordinates_from_the_kind(module):
    tuples = _string_tuples(ROOT / module)
    assert not any({"psi", "theta"} <= set(t) for t in tuples), module


def test_rolls_are_not_found_by_their_names():
    source = (ROOT / "fpr/model/robot.py").read_text(encoding="utf-8")
    assert 'startswith("phi")' not in source


def test_the_simulation_summary_reports_the_kinds_out_of_plane_coordinates(monkeypatch):
    from fpr.sim.closed_loop import SimulationLog

    robot = fpr.load("fpr")
    n, n_d = 3, robot.n_drones
    q = np.zeros((n, robot.nq))
    q[:] = 0.1 * np.arange(1, robot.nq + 1)
    log = SimulationLog(robot.name, tuple(robot.layout.coordinates), tuple(robot.layout.chain), np.arange(n) * 0.1,
                        q, np.zeros_like(q), np.zeros((3, n, len(robot.layout.chain))), np.zeros((n, n_d)),
                        np.zeros((n, n_d)), np.ones((n, n_d, 4)), np.ones((n, n_d, 4)), np.ones((n, n_d)),
                        np.zeros((n, n_d, 3)), np.zeros((n, n_d, 4), dtype=bool), np.zeros((n, n_d)), np.zeros(n),
                        1.0, 1.0, 1.0)
    summary = log.summary()["max_abs_out_of_plane"]
    assert list(summary) == ["x", "psi", "theta"]
    assert summary["psi"] == pytest.approx(0.1 * (robot.index["psi"] + 1))
    monkeypatch.setattr(Fpr, "out_of_plane", ("theta",))
    assert list(log.summary()["max_abs_out_of_plane"]) == ["theta"]


# ---------------------------------------------------------------------- what the drones must do, through the kind
def _sine_motion(robot, count=9):
    """s(t) = s0 + 0.2 sin(w t + p) and its derivatives 0..4 at ``count`` samples, shape (5, N, n_s)."""
    t = np.linspace(0.0, 1.5, count)
    n = len(robot.layout.chain)
    omega, phase = np.linspace(1.0, 2.0, n), np.linspace(0.0, 1.0, n)
    arg = omega * t[:, None] + phase
    s0 = np.array(robot.kind.reference_chain)
    return np.array([s0 * (k == 0) + 0.2 * omega**k * np.sin(arg + k * np.pi / 2) for k in range(5)])


def test_inverse_dynamics_asks_the_kind(robot, monkeypatch):
    from fpr.model import inverse_dynamics as idyn

    motion = _sine_motion(robot)
    sentinel = object()
    monkeypatch.setattr(type(robot.kind), "motion_inputs", lambda self, m, external=None: (sentinel, m, external))
    assert idyn.inverse_dynamics(robot, motion, external="gust") == (sentinel, motion, "gust")


def test_the_planar_kinds_fill_the_generic_attitude_fields_with_their_rolls(robot):
    from fpr.model.inverse_dynamics import inverse_dynamics, planar_inverse_dynamics

    motion = _sine_motion(robot)
    inputs = inverse_dynamics(robot, motion)
    plain = planar_inverse_dynamics(robot, motion)
    np.testing.assert_array_equal(inputs.thrust_vector, plain.thrust_vector)
    n, n_d = motion.shape[1], robot.n_drones
    k_a = {len(c) for c in robot.layout.drone_attitude}.pop()
    for field, roll in (("attitude", inputs.roll), ("attitude_rate", inputs.roll_rate),
                        ("attitude_acceleration", inputs.roll_acceleration)):
        value = getattr(inputs, field)
        assert value.shape == (n, n_d, k_a)
        np.testing.assert_array_equal(value[..., 0], roll)
    np.testing.assert_array_equal(inputs.attitude_rate_squared, inputs.roll_rate**2)
    assert inputs.thrust_vector.shape == (n, n_d, len(robot.kind.force_axes))


def test_full_state_is_the_kinds_and_puts_the_rolls_where_the_layout_says(robot):
    from fpr.model.inverse_dynamics import inverse_dynamics

    motion = _sine_motion(robot)
    inputs = inverse_dynamics(robot, motion)
    states = inputs.full_state(robot)
    assert all(a is b or np.array_equal(a, b) for a, b in zip(states, robot.kind.full_state(inputs), strict=True))
    others = [i for i, c in enumerate(robot.layout.coordinates) if c not in robot.layout.chain + robot.layout.rolls]
    for k, (state, roll) in enumerate(zip(states, (inputs.roll, inputs.roll_rate, inputs.roll_acceleration),
                                          strict=True)):
        np.testing.assert_array_equal(state[:, robot.indices(robot.layout.chain)], motion[k])
        for i, drone in enumerate(robot.layout.drone_attitude):
            np.testing.assert_array_equal(state[:, robot.index[drone[0]]], roll[:, i])
        assert not state[:, others].any()  # the out-of-plane coordinates stay at 0


def test_constraint_rows_take_the_attitude_rows_from_the_kind_in_the_drones_order(robot):
    from fpr.model.inverse_dynamics import inverse_dynamics
    from planners.problem.motion import constraint_rows, objective_rates

    motion = _sine_motion(robot)
    inputs = inverse_dynamics(robot, motion)
    rows, names, details = constraint_rows(robot, motion, inputs, scaled=True)
    limit = np.pi / 2 - robot.margins.angle
    first = len(robot.kind.workspace_margins(motion[0]))
    per_drone = 2 + 8  # two roll rows, then two rows per rotor
    for i in range(robot.n_drones):
        at = first + i * per_drone
        assert names[at:at + 2] == [f"roll_{i + 1}"] * 2 and details[at:at + 2] == ["negative", "positive"]
        np.testing.assert_array_equal(rows[:, at], limit + inputs.roll[:, i])
        np.testing.assert_array_equal(rows[:, at + 1], limit - inputs.roll[:, i])
        assert names[at + 2] == f"rotor_speed_low_{i + 1}"
    # J_phi's integrand is the sum of the drones' squared roll rates
    np.testing.assert_array_equal(objective_rates(inputs)[:, 1], (inputs.roll_rate**2).sum(-1))
