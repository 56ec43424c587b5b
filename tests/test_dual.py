"""Dual numbers (fpr.model.dual): the planner's node sensitivities by dual numbers equal the complex step's,
and every Dual operation the models use equals the complex step's derivative.
"""

import numpy as np
import pytest

from fpr.model import jets
from fpr.model.dual import Dual, gather, lift
from fpr.model.jets import Jet
from fpr.model.rotors import signed_speeds
from planners.methods.one_step import one_step_problem
from planners.methods.two_step import travel_problem
from planners.methods.way_points import WayPointTask
from planners.missions.mission import load_mission
from planners.optimisation.solving import Grid
from planners.problem.motion import MotionProblem

H = 1e-30


def _both(problem, x):
    """_node_derivatives by complex step and by dual numbers at x."""
    points = problem.points_of(x)
    motion = problem.motion(points)
    out = {}
    for way in ("complex", "dual"):
        problem.derivatives = way
        out[way] = problem._node_derivatives(points, motion)
    del problem.derivatives
    return out["complex"], out["dual"]


def _assert_same(reference, dual):
    raw, rows, sens_raw, sens_rows = reference
    # the values to round-off (the complex step's come through complex inversions and products; near the
    # crossing's singularity a quotient's conditioning amplifies it: the Python and the native jets, which sum in
    # other orders, differ there by a few 1e-13 relative)
    np.testing.assert_allclose(dual[0], raw, rtol=1e-11, atol=1e-14 * np.abs(raw).max())
    np.testing.assert_allclose(dual[1], rows, rtol=1e-11, atol=1e-14 * np.abs(rows).max())
    for ref, got in ((sens_raw, dual[2]), (sens_rows, dual[3])):
        assert got.shape == ref.shape
        scale = np.abs(ref).max(axis=(-2, -1), keepdims=True)  # each quantity's sensitivities' size
        assert np.all(np.abs(got - ref) <= 1e-12 * scale + 1e-300)


@pytest.fixture(scope="module")
def square():
    mission = load_mission("square")
    return WayPointTask.of(mission, mission.load_robot())


@pytest.mark.parametrize("mission", ["square", "prototype-tour"])
def test_one_step_nlp_dual_equals_complex_step(mission):
    m = load_mission(mission)
    problem = one_step_problem(WayPointTask.of(m, m.load_robot()), Grid())
    x = problem.x_of(problem.points)
    rng = np.random.default_rng(1)
    for step in (0.0, 0.01):
        _assert_same(*_both(problem, x + step * rng.standard_normal(x.size)))


def test_two_step_travel_dual_equals_complex_step(square):
    grid = Grid()
    points, durations, is_way = square.via_layout
    way = np.flatnonzero(is_way)
    travel = travel_problem(square, points.copy(), durations, way[0], way[1], square.normalisation(grid),
                            grid)
    x = travel.x_of(points[way[0]:way[1] + 1])
    _assert_same(*_both(travel, x + 0.01 * np.random.default_rng(2).standard_normal(x.size)))


def test_evaluation_is_the_same_either_way(square):
    problem = one_step_problem(square, Grid())
    x = problem.x_of(problem.points)
    ev = {}
    for way in ("complex", "dual"):
        problem.derivatives = way
        ev[way] = MotionProblem.evaluate.__wrapped__(problem, x, True)
    del problem.derivatives
    np.testing.assert_allclose(ev["dual"].gradient, ev["complex"].gradient, rtol=1e-12,
                               atol=1e-12 * np.abs(ev["complex"].gradient).max())
    assert ev["dual"].J == pytest.approx(ev["complex"].J, rel=1e-15)


# --- the operations against complex step -------------------------------------------------------------------
def _pair(rng, shape, directions=3, scale=1.0, positive=False):
    """A Dual with random tangents and the complex-step copies of the same (copy-major, (D,) + shape)."""
    value = rng.uniform(0.5 if positive else -scale, scale + (1.0 if positive else 0.0), shape)
    tangents = rng.standard_normal((directions,) + shape)
    return Dual(value, tangents), value[None] + 1j * H * tangents


def _check(dual, cs):
    """dual's value and tangents equal the complex step's (cs (D,) + shape)."""
    np.testing.assert_allclose(dual.value, np.broadcast_to(cs.real[0], dual.shape), rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(dual.full_tangents(cs.shape[0]), cs.imag / H, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name, f", [
    ("add", lambda a, b: a + b), ("sub", lambda a, b: a - b), ("mul", lambda a, b: a * b),
    ("div", lambda a, b: a / (b + 3.0)), ("matmul", lambda a, b: a @ b),
    ("const", lambda a, b: 2.0 * a - 1.0 + a / 4.0), ("rconst", lambda a, b: 1.0 / (a + 3.0) - (2.0 - b)),
])
def test_arithmetic(name, f):
    rng = np.random.default_rng(10)
    (a, ac), (b, bc) = _pair(rng, (6, 4, 4)), _pair(rng, (6, 4, 4))
    _check(f(a, b), f(ac, bc))


def test_elementary_functions():
    rng = np.random.default_rng(11)
    a, ac = _pair(rng, (7, 3), positive=True)
    b, bc = _pair(rng, (7, 3))
    _check(np.sin(a), np.sin(ac))
    _check(np.cos(a), np.cos(ac))
    _check(np.sqrt(a), np.sqrt(ac))
    _check(np.arctan2(b, a), jets._atan2_value(bc, ac))
    sin, cos = jets.sin_cos_value(b)
    _check(sin, np.sin(bc))
    _check(cos, np.cos(bc))
    w2 = Dual(np.array([[4.0, -9.0, 0.0]]), np.ones((2, 1, 3)))
    speeds = signed_speeds(w2)
    np.testing.assert_array_equal(speeds.value, [[2.0, -3.0, 0.0]])
    np.testing.assert_array_equal(speeds.tangents[:, 0], [[0.25, 1.0 / 6.0, 0.0]] * 2)


def test_linear_algebra():
    rng = np.random.default_rng(12)
    a, ac = _pair(rng, (5, 4, 4))
    a.value += 4 * np.eye(4)
    ac += 4 * np.eye(4)
    b, bc = _pair(rng, (5, 4, 2))
    _check(jets.small_matmul(a, b), ac @ bc)
    _check(jets.inverse(a), np.linalg.inv(ac))
    _check(jets.solve_matrices(a, b), np.linalg.solve(ac, bc))


def test_jets_of_duals():
    """Jet products, quotients, square roots, sines and solves of Jets of Duals (the motion's jets)."""
    rng = np.random.default_rng(13)
    (a, ac), (b, bc) = _pair(rng, (3, 6, 4, 4)), _pair(rng, (3, 6, 4))
    a.value[0] += 4 * np.eye(4)
    ac[:, 0] += 4 * np.eye(4)
    p, pc = _pair(rng, (3, 6), positive=True)
    ja, jb, jp = Jet(a), Jet(b), Jet(p)
    per_copy = [(Jet(ac[d]), Jet(bc[d]), Jet(pc[d])) for d in range(ac.shape[0])]
    cases = [
        (lambda x, y, z: jets.matmul(x, y[..., None])[..., 0]),
        (lambda x, y, z: jets.solve(x, y)),
        (lambda x, y, z: y / z[..., None] + z[..., None] * y),
        (lambda x, y, z: jets.sqrt(z)),
        (lambda x, y, z: jets.sincos(z)[0] * jets.sincos(y[..., 0])[1]),
        (lambda x, y, z: jets.atan2(-y[..., 0], z + 2.0)),
    ]
    for f in cases:
        got = f(ja, jb, jp).d
        _check(got, np.stack([f(*c).d for c in per_copy]))


def test_directions_carried_and_widened():
    """A Dual carries the directions it depends on; combining others widens it, assigning checks it."""
    rng = np.random.default_rng(14)
    x = Dual.seeded(rng.standard_normal((3, 5, 2)), [(r, slice(None), j) for r in range(3) for j in range(2)])
    assert (x[0].lo, x[0].hi, x[1:].lo, x[1:].hi, x[:2].hi) == (0, 2, 2, 6, 4)
    y = x[0] * x[2] + np.sin(x[1])
    assert (y.lo, y.hi) == (0, 6)
    np.testing.assert_array_equal(y.full_tangents(6)[:2], (x[0].full_tangents(6) * x[2].value)[:2])
    g = gather(np.zeros(3), [(np.ones((1, 3)), 4), (2 * np.ones((2, 3)), 1)])
    np.testing.assert_array_equal(g.full_tangents(6)[:, 0], [0, 2, 2, 0, 1, 0])
    narrow = lift(np.zeros(3), 0, 1)
    with pytest.raises(ValueError, match="directions"):
        narrow[...] = g
    with pytest.raises(TypeError):
        np.asarray(g)
    where = np.where(np.array([True, False, True]), g, narrow)
    np.testing.assert_array_equal(where.full_tangents(6)[:, 1], 0.0)
    cat = np.concatenate([g, narrow, np.ones(2)])
    assert cat.shape == (8,) and (cat.lo, cat.hi) == (0, 5)


def test_dual_numbers_everywhere_but_for_a_complex_motion(square):
    """Dual numbers by default, on every problem (a single travel, the whole mission); the complex step for a
    complex motion (a caller's own complex step through the problem) whatever the setting, and on request.
    """
    grid = Grid()
    big = one_step_problem(square, grid)
    points, durations, is_way = square.via_layout
    way = np.flatnonzero(is_way)
    small = travel_problem(square, points.copy(), durations, way[0], way[1], square.normalisation(grid), grid)
    motion = {p: p.motion(p.points) for p in (big, small)}
    assert MotionProblem.derivatives == "dual"
    assert big._dual_derivatives(motion[big]) and small._dual_derivatives(motion[small])
    assert not small._dual_derivatives(motion[small] + 0j)
    small.derivatives = "complex"
    assert not small._dual_derivatives(motion[small])


def test_crossing_nlp_dual_equals_complex_step():
    """The prototype crossing its singularity (motion derivatives 0..6, the crossing's side rows): dual numbers
    equal the complex step there too.
    """
    from planners.crossing.problem import crossing_layout
    from planners.crossing.solve import first_guess

    m = load_mission("cross-singularity")
    robot = m.load_robot()
    poses = m.positions(robot)
    n_via = tuple(int(n) for n in m.via_points)
    guess = first_guess(robot, poses[0], poses[-1], float(np.sum(m.times)), n_via)
    crossing, _ = crossing_layout(n_via)
    free = np.ones(guess.points.shape, dtype=bool)
    free[[0, -1]] = False
    problem = MotionProblem(robot, guess.points, guess.durations, free, 0.5, (1.0, 1.0), crossing=crossing)
    x = problem.x_of(problem.points)
    _assert_same(*_both(problem, x + 1e-3 * np.random.default_rng(4).standard_normal(x.size)))


def test_trimmed_drops_the_directions_a_dual_does_not_depend_on():
    from fpr.model.dual import trimmed

    t = np.zeros((6, 3))
    t[2, 0], t[4, 2] = 1.0, 2.0
    x = trimmed(Dual(np.ones(3), t, 1))
    assert (x.lo, x.hi) == (3, 6)
    np.testing.assert_array_equal(x.full_tangents(7), np.concatenate([np.zeros((1, 3)), t]))
    assert trimmed(np.ones(2)).shape == (2,) and trimmed(Dual(np.ones(3), np.zeros((4, 3)))).hi == 0


def test_disturbed_problem_dual_equals_complex_step():
    """A problem whose inputs are flown in a gust (DisturbedProblem overrides _inputs) takes Duals too."""
    from planners.missions.events import GustEvent
    from planners.optimize import plan
    from planners.problem.disturbance import DisturbedProblem
    from planners.replanning.replanner import Replanner, ReplanOptions

    mission = load_mission("moving-target")
    replanner = Replanner(plan(mission, "two-step"), ReplanOptions())
    replanner.move(0)
    problem, x0, _, _ = replanner.problem(4.05)
    gust = GustEvent(4.2, (0.0, -8.0, -4.0), 0.8)
    disturbed = DisturbedProblem(problem.robot, problem.points, problem.durations, problem.free,
                                 problem.alpha, problem.normalisation, gusts=[gust], start_time=4.05,
                                 samples_per_segment=problem.samples_per_segment)
    _assert_same(*_both(disturbed, x0))
