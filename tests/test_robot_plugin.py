"""A third robot defined outside the library (tests/robots/unequal_fpr: one xacro file, one robot module) is
registered with one line, then loaded, planned and simulated in closed loop by the library's generic code.

The robot is the FPR with links of 0.9 m and 0.6 m and a heavier drone 2 hinged closer to its centre of
mass, so that every place that assumes equal links or identical drones shows. Physics checked, not
"it ran": the Pinocchio model against an independent hand derivation of the planar Lagrangian, the
closed chain against the minimal model, hover inputs against gravity in the exact plant, a plan
feasible on the dense grid, and closed-loop tracking.

Tolerances: hand model vs Pinocchio at 1e-12 (closed forms both); closed chain at 1e-9 (as
tests/test_constrained.py); hover 1e-4 m over 1 s (as tests/test_plant.py); tracking 1 cm / 0.01 rad
(as the square mission in tests/test_simulate.py).
"""

import importlib.metadata
from pathlib import Path

import numpy as np
import pytest
from robots.unequal_fpr.robot import UnequalFpr

import fpr
import fpr.robots
from fpr.model.constrained import build_closed_chain
from fpr.model.errors import NotUniformError
from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.robots.base import RobotKind
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.plant import Plant, hover_configuration, hover_speeds
from planners.missions.mission import Mission
from planners.optimize import plan

SEED = 5
S0 = np.array([0.0, 0.0, 5 * np.pi / 4, np.pi / 2])
XACRO = {"link_1_length": 0.9, "link_2_length": 0.6, "link_2_mass": 0.08, "drone_2_mass": 1.3,
         "drone_2_hinge_offset": 0.05}  # the defaults of unequal_fpr.urdf.xacro


def test_an_installed_package_registers_by_entry_point(monkeypatch):
    """A package that declares the robot in the entry-point group fpr.robots needs no register() line: the
    registry loads it on the first look-up (so ``python -m fpr.plan`` knows it too).
    """
    entry = importlib.metadata.EntryPoint("unequal_fpr", "robots.unequal_fpr.robot:UnequalFpr", "fpr.robots")
    monkeypatch.setattr(importlib.metadata, "entry_points",
                        lambda group=None: [entry] if group == fpr.robots.ENTRY_POINT_GROUP else [])
    monkeypatch.setattr(fpr.robots, "_entry_points_loaded", False)
    assert fpr.robots.get("unequal_fpr") is UnequalFpr and "unequal_fpr" in fpr.robots.names()
    fpr.robots.unregister("unequal_fpr")


@pytest.fixture(scope="module")
def robot():
    fpr.robots.register(UnequalFpr)  # the one line a third robot needs
    yield fpr.load("unequal_fpr")
    fpr.robots.unregister("unequal_fpr")


@pytest.fixture(scope="module")
def planned(robot):
    mission = Mission(name="hop", robot="unequal_fpr", way_points=[S0, S0 + [0.4, 0.3, 0.0, 0.0]], times=[2.5])
    return plan(mission, "two-step")


def test_the_description_reaches_the_model(robot):
    p = robot.parameters
    assert robot.kind.link_lengths == pytest.approx((XACRO["link_1_length"], XACRO["link_2_length"]), abs=1e-12)
    np.testing.assert_allclose(robot.drone_masses, [p["drone_mass"], XACRO["drone_2_mass"]], atol=1e-12)
    np.testing.assert_allclose(robot.hinge_offsets, [p["hinge_offset"], XACRO["drone_2_hinge_offset"]], atol=1e-12)
    assert robot.total_mass == pytest.approx(p["drone_mass"] + XACRO["drone_2_mass"] + p["link_mass"]
                                             + XACRO["link_2_mass"] + p["end_effector_mass"], abs=1e-12)
    with pytest.raises(NotUniformError, match="drone_masses"):
        robot.drone_mass  # noqa: B018  (one mass for drones that differ: refused, not drone 1's)
    assert robot.kind.ground_height == -XACRO["link_1_length"]
    # the kind's own xacro arguments are accepted by load, and by a mission
    other = fpr.load("unequal_fpr", link_2_length=0.7)
    assert other.kind.link_lengths == pytest.approx((0.9, 0.7), abs=1e-12)
    mission = Mission(name="m", robot="unequal_fpr", way_points=[S0, S0], times=[1.0],
                      robot_parameters={"link_2_length": 0.7})
    assert mission.load_robot().kind.link_lengths == pytest.approx((0.9, 0.7), abs=1e-12)


def _rod(sel, length, row):
    """Position and Jacobian of p + length u(row . q) (and its angle row), hand-written, q = [y z phi q21 phi1 phi2]."""
    def point(q):
        a = row @ q
        return (sel @ q + length * np.array([np.cos(a), np.sin(a)]),
                sel + length * np.outer([-np.sin(a), np.cos(a)], row))
    return point


def hand_model(robot, q):
    """M and the gravity terms g of the planar FPR with unequal links, from the Lagrangian (independent of
    fpr.model.planar and of Pinocchio): bodies at p, p - L_i/2 u(.), drone centres r_i + d_i (-sin phi_i, cos phi_i).
    """
    p = robot.parameters
    l1, l2 = XACRO["link_1_length"], XACRO["link_2_length"]
    d1, d2 = p["hinge_offset"], XACRO["drone_2_hinge_offset"]
    sel = np.zeros((2, 6))
    sel[0, 0] = sel[1, 1] = 1.0
    phi, phi12, phi1, phi2 = np.eye(6)[2], np.eye(6)[2] + np.eye(6)[3], np.eye(6)[4], np.eye(6)[5]

    def rod_inertia(mass, length):
        return mass * (3 * p["link_radius"] ** 2 + length**2) / 12

    def drone_centre(length, row, d, roll):
        hinge = _rod(sel, -length, row)
        def point(q):
            r, j = hinge(q)
            a = roll @ q
            return r + d * np.array([-np.sin(a), np.cos(a)]), j + d * np.outer([-np.cos(a), -np.sin(a)], roll)
        return point

    bodies = [  # (mass, inertia about x, centre of mass, angle row)
        (p["end_effector_mass"], 0.4 * p["end_effector_mass"] * p["end_effector_radius"] ** 2,
         _rod(sel, 0.0, phi), phi),
        (p["link_mass"], rod_inertia(p["link_mass"], l1), _rod(sel, -l1 / 2, phi), phi),
        (XACRO["link_2_mass"], rod_inertia(XACRO["link_2_mass"], l2), _rod(sel, -l2 / 2, phi12), phi12),
        (p["drone_mass"], p["drone_ixx"], drone_centre(l1, phi, d1, phi1), phi1),
        (XACRO["drone_2_mass"], p["drone_ixx"], drone_centre(l2, phi12, d2, phi2), phi2),
    ]
    m, g = np.zeros((6, 6)), np.zeros(6)
    for mass, inertia, centre, row in bodies:
        _, jac = centre(q)
        m += mass * jac.T @ jac + inertia * np.outer(row, row)
        g += mass * p["gravity"] * jac[1]
    return m, g


def test_mass_matrix_against_the_hand_derivation(robot):
    rng = np.random.default_rng(SEED)
    planar = robot.planar_indices()
    for _ in range(5):
        q = np.zeros(robot.nq)
        q[planar] = np.concatenate([S0, [0.0, 0.0]]) + 0.4 * rng.normal(size=6)
        m_hand, g_hand = hand_model(robot, q[planar])
        np.testing.assert_allclose(robot.mass_matrix(q)[np.ix_(planar, planar)], m_hand, atol=1e-12)
        np.testing.assert_allclose(robot.gravity_terms(q)[planar], g_hand, atol=1e-12)
        np.testing.assert_allclose(robot.planar("rigid").mass_matrix(q[planar]), m_hand, atol=1e-12)


def test_closed_forms_equal_the_generic_defaults(robot):
    """The FPR's closed-form kinematics with L1 != L2 against RobotKind's defaults, read off the planar model."""
    rng = np.random.default_rng(SEED + 2)
    s = S0 + 0.3 * rng.normal(size=(20, 4))
    s_dot = rng.normal(size=(20, 4))
    kind = robot.kind
    np.testing.assert_allclose(kind.drone_joints(s), RobotKind.drone_joints(kind, s), atol=1e-12)
    np.testing.assert_allclose(kind.chain_jacobian(s), RobotKind.chain_jacobian(kind, s), atol=1e-12)
    np.testing.assert_allclose(kind.drone_joint_velocities(s, s_dot), RobotKind.drone_joint_velocities(kind, s, s_dot),
                               atol=1e-12)


def test_closed_chain_is_the_minimal_model(robot):
    """The FPR kind's closure built for unequal links: same accelerations as the minimal model, exact round trip."""
    closed = build_closed_chain(robot)
    rng = np.random.default_rng(SEED + 1)
    for _ in range(5):
        q = robot.configuration(phi=S0[2], q21=S0[3]) + 0.3 * rng.normal(size=robot.nq)
        v = rng.normal(size=robot.nq)
        thrust, torque = rng.uniform(3, 15, 2), 0.3 * rng.normal(size=(2, 3))
        a = robot.forward_dynamics(q, v, thrust, torque)
        qc, vc, expected = closed.from_minimal(q, v, a)
        assert closed.closure_error(qc) < 1e-12
        ac = closed.forward_dynamics(qc, vc, closed.generalized_input(qc, thrust, torque))
        np.testing.assert_allclose(ac, expected, atol=1e-9 * (1 + np.abs(expected).max()))
        back_q, back_v = closed.to_minimal(qc, vc, reference=q)
        np.testing.assert_allclose(back_q, q, atol=1e-12)
        np.testing.assert_allclose(back_v, v, atol=1e-9)


def test_hover_inputs_balance_gravity(robot):
    """At rest the thrusts carry the whole weight (Newton for the whole robot), and the exact plant holds still."""
    still = np.zeros((5, 1, 4))
    still[0, 0] = S0
    inputs = inverse_dynamics(robot, still)
    weight = robot.total_mass * robot.planar("point").gravity
    np.testing.assert_allclose(inputs.thrust_vector[0].sum(axis=0), [0.0, weight], atol=1e-10)
    along_thrust = inputs.thrust[0, :, None] * np.stack([-np.sin(inputs.roll[0]), np.cos(inputs.roll[0])], -1)
    np.testing.assert_allclose(along_thrust, inputs.thrust_vector[0], atol=1e-12)
    assert inputs.thrust[0, 1] > inputs.thrust[0, 0]  # the heavier drone 2 on the shorter link lifts more
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    plant = Plant.from_minimal(robot, q, w=w)
    start = plant.drone_positions()
    for _ in range(1000):
        plant.step(w, 1e-3)
    assert np.abs(plant.drone_positions() - start).max() < 1e-4


def test_plan_is_feasible_on_the_dense_grid(robot, planned):
    assert planned.robot.name == "unequal_fpr" and planned.feasible, [c.name for c in planned.report.violations]
    motion = planned.report.motion
    np.testing.assert_allclose(motion[0][[0, -1]], [S0, S0 + [0.4, 0.3, 0.0, 0.0]], atol=1e-12)
    margins = robot.kind.workspace_margins(motion[0])
    assert min(v.min() for v in margins.values()) > 0
    # the drone joints the plan reports are where links of 0.9 m and 0.6 m put them
    joints = planned.report.inputs.joint_position
    np.testing.assert_allclose(np.linalg.norm(joints - motion[0][:, None, :2], axis=-1),
                               np.broadcast_to([0.9, 0.6], joints.shape[:2]), atol=1e-12)


@pytest.fixture(scope="module")
def log(planned):
    return simulate(planned, SimulationSettings(hold=0.5))


def test_closed_loop_tracks_the_plan(robot, planned, log):
    err = np.abs(log.tracking_error)
    assert log.robot_name == "unequal_fpr"
    assert err[:, :2].max() < 0.01 and err[:, 2:].max() < 0.01, err.max(axis=0)
    summary = log.summary()
    assert summary["max_closure_error_m"] < 1e-9 and summary["saturated_ticks"] == 0
    assert summary["peak_rotor_speed_rad_s"] < summary["planning_speed_limit_rad_s"]


def test_the_views_draw_it(robot, planned, log, tmp_path):
    """Every figure of the plan and of the simulation, with the kind's titles; the ground at z = -L1."""
    import matplotlib

    matplotlib.use("Agg")
    from fpr.views.figures import FIGURE_SET, figure_set

    paths = figure_set(tmp_path, planned, log=log)
    assert tuple(paths) == FIGURE_SET and all(Path(p).stat().st_size > 0 for p in paths.values())
    assert all(title.endswith("(unequal FPR)") for title in robot.kind.titles.values())
    assert robot.kind.ground_height == pytest.approx(-0.9)
