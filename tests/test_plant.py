"""The simulated plant: closed-chain dynamics under rotor speeds, motor lag, saturation, wind."""

import numpy as np
import pytest
from helpers import random_state

import fpr
from fpr.model.errors import ModelArgumentError
from fpr.sim.plant import Plant, PlantDivergedError, hover_configuration, hover_speeds, plant_step_time

SEED = 23
DT = 1e-3


def hovering(name, **coordinates):
    """A robot, a static pose at its reference chain (with the given x / psi), and its hover speeds."""
    robot = fpr.load(name)
    q = hover_configuration(robot, robot.kind.reference_chain)
    for c, value in coordinates.items():
        q[robot.index[c]] = value
    return robot, q, hover_speeds(robot, q)


@pytest.mark.parametrize("name, coordinates", [("fpr", {"x": 0.4, "psi": 0.7}), ("prototype", {"psi": -0.5})])
def test_hover_speeds_hold_the_pose(name, coordinates):
    """2 s at the hover speeds (yawed, and off the plane for the FPR): the drones move less than 1e-4 m and
    the measured state is the initial one.
    """
    robot, q, w = hovering(name, **coordinates)
    plant = Plant.from_minimal(robot, q, w=w)
    start = plant.drone_positions()
    for _ in range(int(round(2.0 / DT))):
        plant.step(w, DT)
    assert plant.time == pytest.approx(2.0)
    assert np.abs(plant.drone_positions() - start).max() < 1e-4
    q_end, v_end = plant.measure()
    np.testing.assert_allclose(q_end, q, rtol=0, atol=1e-6)
    np.testing.assert_allclose(v_end, 0.0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(plant.rotor_speeds, w, rtol=0, atol=1e-9)


def test_hover_speeds_refuse_a_pose_that_is_not_static():
    robot, q, _ = hovering("fpr")
    q[robot.index["phi1"]] += 0.1
    with pytest.raises(ModelArgumentError, match="not a static pose"):
        hover_speeds(robot, q)
    q = hover_configuration(robot, robot.kind.reference_chain)
    q[robot.index["theta"]] = 0.2  # the plane tilted: gravity pulls it out of the plane
    with pytest.raises(ModelArgumentError, match="theta"):
        hover_speeds(robot, q)


def test_passive_prototype_swings_with_constant_energy():
    """Rotors stopped, the prototype swings and spins about its fixed point for 3 s: energy constant to
    1e-4 J (RKMK4 at 1 ms), the loop closed to 1e-5 m.
    """
    robot = fpr.load("prototype")
    q = robot.configuration(q1=0.3, q2=1.2, phi1=0.5)
    v = robot.configuration(psi=0.5, theta=0.2, q1=1.0, phi1=2.0)
    plant = Plant.from_minimal(robot, q, v)
    e0, worst_energy, worst_closure = plant.energy(), 0.0, 0.0
    stopped = np.zeros((1, 4))
    for k in range(int(round(3.0 / DT))):
        plant.step(stopped, DT)
        if k % 10 == 0:
            worst_energy = max(worst_energy, abs(plant.energy() - e0))
            worst_closure = max(worst_closure, plant.closure_error())
    assert worst_energy < 1e-4
    assert worst_closure < 1e-5
    assert np.abs(plant.measure()[0] - q).max() > 0.1  # it did move


def test_measure_is_continuous_and_consistent_while_flailing():
    """The FPR falling with rotors stopped and a large roll rate (phi crosses +-pi and goes past 5pi/4 + pi):
    successive measurements move by small steps, and the minimal model at the measured q puts the drones
    where the plant has them (1e-6 m).
    """
    robot = fpr.load("fpr")
    q, v = random_state(robot, np.random.default_rng(SEED), scale=0.5)
    v[robot.index["phi"]] = 8.0
    plant = Plant.from_minimal(robot, q, v)
    previous = q
    stopped = np.zeros((2, 4))
    for _ in range(1000):
        plant.step(stopped, DT)
        q, _ = plant.measure()
        assert np.abs(q - previous).max() < 0.05
        previous = q
        assert np.abs(robot.drone_positions(q) - plant.drone_positions()).max() < 1e-6
    assert q[robot.index["phi"]] > 5 * np.pi / 4 + np.pi  # the roll left the default range, continuously


def test_motor_lag_is_first_order():
    """After a step in the command, each rotor speed follows w_cmd + (w0 - w_cmd) exp(-t / T_m)."""
    robot, q, w0 = hovering("prototype")
    plant = Plant.from_minimal(robot, q, w=w0)
    command = w0 + np.array([[100.0, -50.0, 20.0, 0.0]])
    lag = robot.rotor_constants.time_constant
    for k in range(1, 61):
        plant.step(command, DT)
        np.testing.assert_allclose(plant.rotor_speeds, command + (w0 - command) * np.exp(-k * DT / lag),
                                   rtol=0, atol=1e-9)


def test_rotor_speed_commands_are_saturated():
    """Commands above w_max (or below 0) drive the rotors to w_max (or 0), never beyond."""
    robot, q, w0 = hovering("prototype")
    plant = Plant.from_minimal(robot, q, w=w0)
    w_max = robot.rotor_constants.max_speed
    command = np.array([[2 * w_max, -100.0, 1.5 * w_max, w_max]])
    for _ in range(400):
        plant.step(command, DT)
        assert plant.rotor_speeds.max() <= w_max and plant.rotor_speeds.min() >= 0.0
    np.testing.assert_allclose(plant.rotor_speeds, [[w_max, 0.0, w_max, w_max]], rtol=0, atol=1e-6 * w_max)
    np.testing.assert_array_equal(plant.saturate(command), [[w_max, 0.0, w_max, w_max]])


@pytest.mark.parametrize("wind", [np.array([1.0, -2.0, 0.5]), np.array([[0.0, 3.0, 0.0], [1.0, 0.0, -1.0]])])
def test_wind_accelerates_the_centre_of_mass(wind):
    """A constant wind on the hovering FPR: over the first 10 ms the centre of mass accelerates at the total
    wind force over the total mass (within 5 %), since thrust and weight balance and the closure is
    internal.
    """
    robot, q, w = hovering("fpr")
    plant = Plant.from_minimal(robot, q, w=w)
    _, v0 = plant.center_of_mass()
    for _ in range(10):
        plant.step(w, DT, wind=wind)
    _, v1 = plant.center_of_mass()
    total = np.broadcast_to(wind, (2, 3)).sum(axis=0)
    expected = total / robot.total_mass
    np.testing.assert_allclose((v1 - v0) / (10 * DT), expected, rtol=0, atol=0.05 * np.linalg.norm(expected))


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_plant_accelerations_are_the_minimal_model_s(name):
    """Random states and rotor speeds: the plant's accelerations are those of the minimal model
    (robot.forward_dynamics under the thrusts and torques R_f w^2), mapped by from_minimal.
    """
    robot = fpr.load(name)
    rng = np.random.default_rng(SEED + 1)
    for _ in range(10):
        q, v = random_state(robot, rng)
        w = rng.uniform(300.0, 800.0, (robot.n_drones, 4))
        plant = Plant.from_minimal(robot, q, v, w=w)
        thrust, torque = plant.rotor_inputs()
        for i, rotor in enumerate(robot.rotors):
            np.testing.assert_allclose(np.append(thrust[i], torque[i]), rotor.mixing_matrix @ w[i] ** 2)
        a = robot.forward_dynamics(q, v, thrust, torque)
        expected = plant.closed.from_minimal(q, v, a)[2]
        tolerance = 1e-9 * (1 + np.abs(expected).max())
        np.testing.assert_allclose(plant.acceleration(), expected, rtol=0, atol=tolerance)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_rotor_constant_scale_scales_force_and_drag(name):
    """A scale of 0.5: half of every thrust and torque at the same speeds; a negative scale is refused."""
    robot, q, w = hovering(name)
    nominal = Plant.from_minimal(robot, q, w=w)
    half = Plant.from_minimal(robot, q, w=w, rotor_constant_scale=0.5)
    for full, scaled in zip(nominal.rotor_inputs(), half.rotor_inputs(), strict=True):
        np.testing.assert_allclose(scaled, 0.5 * full, rtol=1e-15, atol=0)
    with pytest.raises(ModelArgumentError, match="rotor_constant_scale"):
        Plant.from_minimal(robot, q, w=w, rotor_constant_scale=-1.0)


def test_rotors_without_thrust_let_the_fpr_fall_freely():
    """rotor_constant_scale 0 at hover speeds: no force at all, every drone drops g t^2 / 2 in 0.3 s (1e-6 m),
    the chain keeps its shape.
    """
    robot, q, w = hovering("fpr")
    plant = Plant.from_minimal(robot, q, w=w, rotor_constant_scale=0.0)
    start = plant.drone_positions()
    steps = int(round(0.3 / DT))
    for _ in range(steps):
        plant.step(w, DT)
    drop = start - plant.drone_positions()
    np.testing.assert_allclose(drop, np.tile([0.0, 0.0, 0.5 * 9.81 * (steps * DT) ** 2], (2, 1)), atol=1e-6)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_drone_hinges_tilts_and_speeds(name):
    """What the simulator's watch reads: the hinges are the minimal model's drone joints; in the plane, a
    drone's tilt is |its roll| (in space, the angle of its z axis in the minimal model from the vertical);
    spinning the whole robot about z at 0.5 rad/s gives each drone that angular speed and its hinge the speed
    0.5 times its distance to the axis.
    """
    robot, q, w = hovering(name)
    plant = Plant.from_minimal(robot, q, w=w)
    joints = robot.kind.drone_joints(q[robot.indices(robot.layout.chain)])
    rows = ["xyz".index(a) for a in robot.kind.force_axes]
    np.testing.assert_allclose(plant.drone_joint_positions()[:, rows], joints, rtol=0, atol=1e-12)
    others = [k for k in range(3) if k not in rows]  # a planar robot's hinges are in the plane x = 0
    np.testing.assert_allclose(plant.drone_joint_positions()[:, others], 0.0, atol=1e-12)

    def tilts(q):
        if len(rows) == 2:  # in the plane: |roll|
            return np.abs(q[robot.indices(robot.layout.rolls)])
        return np.arccos(np.clip([p.rotation[2, 2] for p in robot.frame_placements(q)], -1, 1))

    np.testing.assert_allclose(plant.drone_tilts(), tilts(q), atol=1e-9)
    np.testing.assert_allclose(plant.drone_speeds(), 0.0, atol=0)
    roll = robot.layout.drone_attitude[0][-1]  # drone 1's roll (the planar robots' phi1)
    q[robot.index[roll]] = 2.0  # past pi/2: the thrust points down
    assert Plant.from_minimal(robot, q).drone_tilts()[0] == pytest.approx(tilts(q)[0], abs=1e-9)
    assert tilts(q)[0] > np.pi / 2
    v = robot.configuration(psi=0.5)
    q[robot.index[roll]] = 0.0
    linear, angular = Plant.from_minimal(robot, q, v).drone_speeds()
    np.testing.assert_allclose(angular, 0.5, atol=1e-12)
    hinges = plant.drone_joint_positions()
    np.testing.assert_allclose(linear, 0.5 * np.hypot(hinges[:, 0], hinges[:, 1]), atol=1e-12)


def test_plant_errors():
    robot, q, w = hovering("fpr")
    plant = Plant.from_minimal(robot, q, w=w)
    with pytest.raises(fpr.ShapeError, match="w_command"):
        plant.step(w[0], DT)
    with pytest.raises(ModelArgumentError, match="positive"):
        plant.step(w, 0.0)
    with pytest.raises(fpr.ShapeError, match="wind"):
        plant.step(w, DT, wind=np.zeros(2))
    plant.vc[:] = np.nan
    with pytest.raises(PlantDivergedError, match="non-finite"):
        plant.step(w, DT)


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_plant_step_time(name):
    seconds = plant_step_time(name, steps=20)
    assert 0.0 < seconds < 0.05
