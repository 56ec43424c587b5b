"""fpr/model/_multibody.c on inputs the Python side never builds: corrupted constants vectors and specs, wrong
sizes. Each call either works or raises (ValueError, TypeError), never reads out of bounds."""

import numpy as np
import pytest

import fpr
from fpr.model.multibody import kernel
from fpr.sim.plant import Plant, hover_configuration

pytestmark = pytest.mark.skipif(kernel is None, reason="fpr.model._multibody is not built (no C compiler)")


@pytest.fixture(scope="module")
def plant():
    """The prototype's plant with its compiled constants and drone point spec exported."""
    robot = fpr.load("prototype")
    plant = Plant.from_minimal(robot, hover_configuration(robot, robot.kind.reference_chain))
    plant._export()
    return plant


@pytest.mark.parametrize("joint", [1e10, 2.0**31, 2.0**32 + 1.0, -1e10, np.nan, np.inf, 1e300])
def test_points_refuse_a_joint_out_of_range(plant, joint):
    """A point's joint far out of range (whose cast to int is undefined, INT_MIN on x86) is refused, not read
    at o[INT_MIN]."""
    spec = plant._point_spec.copy()
    spec[1] = joint
    with pytest.raises(ValueError):
        kernel.points(plant._plant_constants, plant.qc, spec)


def _integer_fields(constants):
    """Indices of the constants vector's integer fields (fpr/model/multibody.py, model_constants' layout):
    nj, nq, nv, closures, max_iter; per joint type, parent, idx_q, idx_v; per closure its two joints."""
    nj, nv, nc = int(constants[0]), int(constants[2]), int(constants[3])
    fields = [0, 1, 2, 3, 8]
    joints = 11 + nv
    for i in range(nj - 1):
        fields += [joints + 32 * i + k for k in range(4)]
    closures = joints + 32 * (nj - 1)
    for c in range(nc):
        fields += [closures + 10 * c, closures + 10 * c + 4]
    return fields


@pytest.mark.parametrize("bad", [0.5, -0.5, np.nan, np.inf, -np.inf, 1e10, -1e10, 2.0**32 + 1.0, 1e300])
def test_integer_fields_of_the_constants_must_be_whole_numbers_in_range(plant, bad):
    """Every integer field of the constants vector, set to a non-whole number or one out of int's range (whose
    cast is undefined), makes the constants refused."""
    constants = plant._plant_constants
    for index in _integer_fields(constants):
        corrupted = constants.copy()
        corrupted[index] = constants[index] + bad if bad in (0.5, -0.5) else bad
        with pytest.raises(ValueError):
            kernel.rigid_terms(corrupted, plant.qc, plant.vc)


@pytest.mark.parametrize("bad", [0.5, np.nan, 1e10, -1e10, 2.0**31, 1e300])
def test_velocity_and_frame_terms_specs_refuse_non_whole_counts(bad):
    """The counts of the velocity and frame_terms specs (n, rows, nq, the number of blocks or frames, a
    block's first row and joint) out of range or not whole: a ValueError, not an undefined cast or an int
    overflow."""
    from fpr.model.constrained import _minimal_cache
    robot = fpr.load("prototype")
    plant = Plant.from_minimal(robot, hover_configuration(robot, robot.kind.reference_chain))
    constants, spec = _minimal_cache(plant.closed).velocity_spec
    n, rows, nq = int(spec[0]), int(spec[1]), int(spec[2])
    blocks = 3 + nq * n
    q, vc = np.zeros(n), np.zeros(rows)
    assert kernel.velocity(constants, spec, q, vc) is not None
    for index in (0, 1, 2, blocks, blocks + 1, blocks + 2):
        corrupted = spec.copy()
        corrupted[index] = spec[index] + bad if bad == 0.5 else bad
        with pytest.raises(ValueError):
            kernel.velocity(constants, corrupted, q, vc)
    robot._build_attitude_constants()
    constants, spec = robot._attitude_terms
    count = 2 + int(spec[1]) * int(spec[0])
    for index in (0, count):
        corrupted = spec.copy()
        corrupted[index] = spec[index] + bad if bad == 0.5 else bad
        with pytest.raises(ValueError):
            kernel.frame_terms(constants, corrupted, np.zeros(robot.nq), np.zeros(robot.nq))


def test_joints_sharing_configuration_or_velocity_entries_are_refused(plant):
    """Two joints on the same idx_v (or idx_q), the counts still adding up to nv (nq): refused, rather than
    leaving an entry of v no joint owns, its column of M and its nle read uninitialised."""
    constants = plant._plant_constants
    nv = int(constants[2])
    joints = 11 + nv
    one_degree = [i for i in range(int(constants[0]) - 1) if constants[joints + 32 * i] != 1]
    assert len(one_degree) >= 2
    a, b = one_degree[:2]
    for field in (2, 3):  # idx_q, idx_v
        corrupted = constants.copy()
        corrupted[joints + 32 * b + field] = constants[joints + 32 * a + field]
        with pytest.raises(ValueError):
            kernel.rigid_terms(corrupted, plant.qc, plant.vc)


def test_too_many_rotor_speeds_raise_a_value_error(plant):
    """More rotor speeds than the steps hold (64): a ValueError, not NULL without an exception set (a
    SystemError)."""
    nv = plant.vc.size
    w = np.zeros(65)
    with pytest.raises(ValueError, match="rotor speeds"):
        kernel.steps(plant._plant_constants, np.zeros((65, nv)), np.ones(3), plant.qc, plant.vc, w, w, 400.0,
                     1e-3, 1)


def test_rotor_speeds_and_their_map_must_pair_up():
    """w_command of another shape than w (a transposed (4, n_d) command against (n_d, 4) speeds) or the
    force map not transposed ((nv, 4 n_d)): a ValueError, rather than the sizes alone matching and rotors
    paired with the wrong commands or map rows."""
    robot = fpr.load("fpr")
    plant = Plant.from_minimal(robot, hover_configuration(robot, robot.kind.reference_chain))
    plant._export()
    force_map_t, decay = plant._lean_constants(1e-3)[3], plant._lean_constants(1e-3)[0]
    w = np.arange(robot.n_drones * 4, dtype=float).reshape(robot.n_drones, 4)
    assert robot.n_drones > 1 and force_map_t.shape == (w.size, plant.vc.size)

    def run(force_map_t, w_command):
        return kernel.steps(plant._plant_constants, force_map_t, decay, plant.qc, plant.vc, w, w_command,
                            400.0, 1e-3, 1)

    run(force_map_t, w)
    with pytest.raises(ValueError, match="shape"):
        run(force_map_t, np.ascontiguousarray(w.T))
    with pytest.raises(ValueError, match="shape"):
        run(np.ascontiguousarray(force_map_t.T), w)


def test_frame_terms_take_a_frame_per_drone_of_the_attitude_model():
    """frame_terms takes as many frames as the spec holds (the attitude model's compiled part takes 16 drones;
    frame_terms took 8, so a robot of 9 to 16 drones raised a ValueError at every attitude_model): the
    prototype's drone frame 17 times gives 17 equal Jacobians, the one of the single-frame spec."""
    robot = fpr.load("prototype")
    robot._build_attitude_constants()
    constants, spec = robot._attitude_terms
    count = 2 + int(spec[1]) * int(spec[0])
    assert spec[count] == 1
    many = np.concatenate([spec[:count], [17], np.tile(spec[count + 1:], 17)])
    q, v = np.full(robot.nq, 0.1), np.full(robot.nq, 0.2)
    _, _, (one,) = kernel.frame_terms(constants, spec, q, v)
    _, _, jacobians = kernel.frame_terms(constants, many, q, v)
    assert len(jacobians) == 17
    for jacobian in jacobians:
        np.testing.assert_array_equal(jacobian, one)
