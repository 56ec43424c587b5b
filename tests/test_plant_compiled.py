"""The native plant (fpr._native's parts ``plant`` and ``measure``: Pinocchio's C++ algorithms called from
fpr/_native/cpp) against the Python path, its reference, which calls the same algorithms through Pinocchio's
Python bindings.

* The constrained acceleration equals ``pin.constraintDynamics``'s; the native steps follow the Python steps
  (with and without wind) on both robots; a non-finite state stops them at the last finite one.
* The points (drones' centres, closure error) and the measurement (configuration, velocity) equal the Python
  path's.
* Any joint Pinocchio knows: a random model with ball (spherical) joints, a free flyer, revolute, prismatic,
  planar and composite joints and more closures than the robots have, stepped natively and by ``rkmk4_step`` on
  ``pin.constraintDynamics``.
* The whole closed loop: the square's simulation with every native part on and with every part off gives the
  same states to 1e-9.
"""

import numpy as np
import pinocchio as pin
import pytest
from native_parts import native_module, needs_native

import fpr
from fpr import _native as native
from fpr.model.constrained import constraint_data
from fpr.sim.plant import Plant, PlantDivergedError, hover_configuration, hover_speeds, rkmk4_step

pytestmark = needs_native

ROBOTS = ("fpr", "prototype")
DT = 1e-3


def closed_state(name, seed, spread=0.05):
    """A robot's plant (its closed chain as the plant builds it) at a state on the closure near its reference pose:
    a random minimal-coordinate state mapped to the closed chain (a consistent q, v).
    """
    robot = fpr.load(name)
    rng = np.random.default_rng(seed)
    hover = hover_configuration(robot, robot.kind.reference_chain)
    q = hover + spread * rng.normal(size=robot.nq)
    v = rng.normal(size=robot.nq)
    return Plant.from_minimal(robot, q, v, w=hover_speeds(robot, hover)), q, rng


def _run(robot, q, w, on, ticks, steps_per_tick=2, wind=None):
    plant = Plant.from_minimal(robot, q, w=w)
    phases = np.arange(w.size).reshape(w.shape)
    with native.switched(plant=on):
        for k in range(ticks):
            plant.advance(w * (1.0 + 0.03 * np.sin(0.02 * k + phases)), DT, steps_per_tick, wind=wind)
    return plant


@pytest.mark.parametrize("name", ROBOTS)
def test_constrained_acceleration_is_pinocchio_s(name):
    """On and off the closure, under random generalised forces: the native acceleration is pin.constraintDynamics'
    (the same function of the same library) to round-off.
    """
    native_module("plant")
    plant, _, rng = closed_state(name, 3)
    kernel = plant._step_kernel()
    closed = plant.closed
    for k in range(5):
        qc = plant.qc if k == 0 else pin.integrate(closed.model, plant.qc, 0.05 * rng.normal(size=closed.model.nv))
        vc, tau = rng.normal(size=closed.model.nv), rng.normal(size=closed.model.nv)
        a = kernel.dynamics(qc, vc, tau)
        reference = closed.forward_dynamics(qc, vc, tau)
        np.testing.assert_allclose(a, reference, rtol=0, atol=1e-12 * max(1.0, np.abs(reference).max()))


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize("windy", [False, True])
def test_native_steps_follow_the_python_steps(name, windy):
    """0.5 s of varying rotor commands (in a wind, a different force on each drone, or without): the native steps
    and the Python steps end at the same state to 1e-10, the same clock and rotor speeds; the robot moved.
    """
    native_module("plant")
    robot = fpr.load(name)
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    wind = np.array([[0.8, -1.5, 0.4], [-0.6, 1.1, 0.2]])[:robot.n_drones] if windy else None
    python, fast = (_run(robot, q, w, on, 250, wind=wind) for on in (False, True))
    assert fast.time == python.time
    np.testing.assert_allclose(fast.qc, python.qc, rtol=0, atol=1e-10)
    np.testing.assert_allclose(fast.vc, python.vc, rtol=0, atol=1e-9)
    # the rotors' lag in C++ and in numpy: the same sums, to round-off (another CPU may order them otherwise)
    np.testing.assert_allclose(fast.rotor_speeds, python.rotor_speeds, rtol=1e-12)
    assert np.abs(python.vc).max() > 0.05
    if windy:
        calm = _run(robot, q, w, True, 250)
        assert np.abs(fast.qc - calm.qc).max() > 1e-3


def test_a_non_finite_state_stops_the_native_steps_at_the_last_finite_one():
    native_module("plant")
    robot = fpr.load("fpr")
    q = hover_configuration(robot, robot.kind.reference_chain)
    w = hover_speeds(robot, q)
    plant = Plant.from_minimal(robot, q, w=w)
    plant.advance(w, DT, 3)
    assert plant._native_plant is not None
    plant.vc = plant.vc.copy()
    plant.vc[0] = np.nan
    before = plant.qc.copy()
    with pytest.raises(PlantDivergedError) as error:
        plant.advance(w, DT, 5)
    assert error.value.time == pytest.approx(3 * DT)
    np.testing.assert_array_equal(plant.qc, before)


@pytest.mark.parametrize("name", ROBOTS)
def test_observed_positions_and_closure_error_are_the_python_ones(name):
    """observe() with the native plant: the drones' centres and the closure error equal the Python path's to
    1e-15 m, on a plant that flew 0.2 s (a closure error of its own); a NaN state gives a NaN closure error.
    """
    native_module("plant")
    robot = fpr.load(name)
    q = hover_configuration(robot, robot.kind.reference_chain)
    plant = _run(robot, q, hover_speeds(robot, q), True, 100)
    _, _, positions, closure = plant.observe()
    with native.switched(plant=False, measure=False):
        _, _, reference_positions, reference_closure = plant.observe()
    np.testing.assert_allclose(positions, reference_positions, rtol=0, atol=1e-15)
    assert abs(closure - reference_closure) < 1e-15
    assert 0 < reference_closure < 1e-6
    plant.qc = np.full_like(plant.qc, np.nan)
    assert np.isnan(plant._step_kernel().points(plant.qc)[1])
    assert np.isnan(plant.closure_error())


@pytest.mark.parametrize("name", ROBOTS)
def test_measurement_is_the_python_one(name):
    """to_minimal natively (forward kinematics, the kind's reads, the unwrapping, the velocity's least squares)
    equals the Python path's at states on and off the closure, against references a turn away.
    """
    native_module("measure")
    plant, q0, rng = closed_state(name, 7, spread=0.3)
    closed = plant.closed
    for k in range(6):
        v_closed = plant.vc if k == 0 else plant.vc + 0.01 * rng.normal(size=plant.vc.size)
        reference = q0 + 0.2 * rng.normal(size=q0.size) + (2 * np.pi if k % 2 else 0.0)
        q, v = closed.to_minimal(plant.qc, v_closed, reference=reference)
        with native.switched(measure=False):
            q_reference, v_reference = closed.to_minimal(plant.qc, v_closed, reference=reference)
        np.testing.assert_allclose(q, q_reference, rtol=0, atol=1e-13)
        np.testing.assert_allclose(v, v_reference, rtol=0, atol=1e-12 * np.abs(v_reference).max())
    assert np.abs(q - q0).max() > 1.0  # a turn away: the unwrapping took part


def _well_posed(model, q, constraints) -> bool:
    """Whether the closures' rows are independent at q and Pinocchio's proximal solve of them converges there."""
    models = pin.StdVec_RigidConstraintModel()
    for cm in constraints:
        models.append(cm)
    data, datas = constraint_data(model, models)
    settings = pin.ProximalSettings(1e-12, 1e-6, 20)
    pin.constraintDynamics(model, data, q, np.zeros(model.nv), np.zeros(model.nv), models, datas, settings)
    rows = np.linalg.svd(pin.getConstraintsJacobian(model, data, models, datas), compute_uv=False)
    return bool(rows.min() > 1e-2 and settings.iter < settings.max_iter)


def _random_model(seed):
    """A random tree of every kind of joint, ball (spherical) joints among them, and 3D point closures between
    random bodies, which hold at the random configuration returned; more joints and closures than the robots
    have.
    """
    rng = np.random.default_rng(seed)
    model = pin.Model()
    model.gravity = pin.Motion(np.array([0.0, 0.0, -9.81, 0.0, 0.0, 0.0]))
    kinds = [pin.JointModelFreeFlyer, pin.JointModelSpherical, pin.JointModelRX, pin.JointModelRY,
             pin.JointModelRZ, pin.JointModelPX, pin.JointModelPZ, pin.JointModelSphericalZYX,
             pin.JointModelPlanar, lambda: pin.JointModelRevoluteUnaligned(*rng.normal(size=3)),
             pin.JointModelTranslation, lambda: pin.JointModelComposite(pin.JointModelRX()).addJoint(
                 pin.JointModelPY())]
    ids = [0]
    for k in range(18):
        kind = kinds[k % len(kinds)]
        parent = 0 if k == 0 else ids[int(rng.integers(1, len(ids)))]
        placement = pin.SE3(pin.exp3(0.5 * rng.normal(size=3)), 0.3 * rng.normal(size=3))
        joint = model.addJoint(parent, kind(), placement, f"joint_{k}")
        inertia = pin.Inertia(1.0 + rng.random(), 0.1 * rng.normal(size=3), np.diag(0.05 + 0.1 * rng.random(3)))
        model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
        ids.append(joint)
    model.armature = 0.01 * np.ones(model.nv)
    # drawn from the seeded generator: pin.randomConfiguration draws from the C library's unseeded rand()
    q = pin.integrate(model, pin.neutral(model), rng.uniform(-1.0, 1.0, size=model.nv))
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    constraints = pin.StdVec_RigidConstraintModel()
    # A closure is kept when the closures' rows stay independent (a well-posed loop). No Baumgarte corrector: on
    # random loops its gains drive some drawn mechanisms unstable within the 50 steps compared.
    while len(constraints) < 6:
        j1, j2 = (int(j) for j in rng.choice(ids[1:], size=2, replace=False))
        point = 0.1 * rng.normal(size=3)  # on j1, and where it is on j2 at q: the closure holds there
        other = data.oMi[j2].actInv(data.oMi[j1].act(point))
        cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, j1, pin.SE3(np.eye(3), point), j2,
                                      pin.SE3(np.eye(3), other), pin.ReferenceFrame.LOCAL)
        if _well_posed(model, q, [*constraints, cm]):
            constraints.append(cm)
    frames = [model.addFrame(pin.Frame(f"point_{k}", int(ids[k + 1]), pin.SE3(np.eye(3), 0.1 * rng.normal(size=3)),
                                       pin.FrameType.OP_FRAME)) for k in range(3)]
    return model, constraints, frames, q, rng


@pytest.mark.parametrize("seed", [1, 2])
def test_any_joint_pinocchio_knows_runs_natively(seed):
    """A random model (18 joints of every kind, ball joints among them, 6 point closures): the native acceleration
    is pin.constraintDynamics', and 50 native steps follow rkmk4_step on Pinocchio's Python calls to 1e-10.
    """
    module = native_module("plant")
    model, constraints, frames, q, rng = _random_model(seed)
    assert any(model.joints[j].shortname() == "JointModelSpherical" for j in range(model.njoints))
    settings = pin.ProximalSettings(1e-12, 1e-6, 20)
    data, datas = constraint_data(model, constraints)
    nw = 4
    force_map = 0.01 * rng.normal(size=(model.nv, nw))
    kernel = module.Plant(model, data, constraints, datas, settings, np.ascontiguousarray(force_map.T),
                          frames)
    own_data = model.createData()
    pin.initConstraintDynamics(model, own_data, constraints, datas)
    v = 0.1 * rng.normal(size=model.nv)
    tau = rng.normal(size=model.nv)
    a = kernel.dynamics(q, v, tau)
    reference = pin.constraintDynamics(model, own_data, q, v, tau, constraints, datas, settings)
    np.testing.assert_allclose(a, reference, rtol=0, atol=1e-11 * max(1.0, np.abs(reference).max()))
    w = np.full(nw, 3.0)
    command = w * 1.2
    decay = np.exp(-np.array([0.0, 0.5, 1.0]) * DT / 0.05)[:, None]
    qn, vn, wn, done, status = kernel.steps(q, v, w, command, 10.0, decay, DT, 50)
    assert (done, status) == (50, 0)
    q_ref, v_ref, w_ref = q.copy(), v.copy(), w.copy()
    for _ in range(50):
        def acceleration(qs, vs, t, w0=w_ref):
            speeds = command + (w0 - command) * np.exp(-t / 0.05)
            return pin.constraintDynamics(model, own_data, qs, vs, force_map.dot(speeds * speeds), constraints,
                                          datas, settings).copy()
        q_ref, v_ref = rkmk4_step(model, q_ref, v_ref, DT, acceleration)
        w_ref = command + (w_ref - command) * decay[2, 0]
    np.testing.assert_allclose(qn, q_ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(vn, v_ref, rtol=0, atol=1e-8 * max(1.0, np.abs(v_ref).max()))
    np.testing.assert_allclose(wn, w_ref, rtol=1e-14)
    assert np.abs(vn - v).max() > 1e-3  # it moved


def test_the_closed_loop_is_the_python_one():
    """The square's two-step plan simulated (simulate's defaults) with every native part on and with every part
    off: the same states, rotor speeds and thrusts to 1e-9.
    """
    from fpr.sim.closed_loop import SimulationSettings, simulate
    from planners.missions.mission import load_mission
    from planners.optimize import plan

    native_module("plant")
    result = plan(load_mission("square"), "two-step")
    fast = simulate(result, SimulationSettings())
    with native.switched(**dict.fromkeys(native.PARTS, False)):
        python = simulate(result, SimulationSettings())
    assert fast.failure is None and python.failure is None and fast.t.size == python.t.size
    for field in ("q", "v", "speed", "thrust", "closure_error"):
        np.testing.assert_allclose(getattr(fast, field), getattr(python, field), rtol=0, atol=1e-9, err_msg=field)
