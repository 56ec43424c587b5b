"""The native closed loop (fpr._native's part ``loop``, ``fpr/_native/cpp/loop.cpp`` and ``outer.cpp``,
:mod:`fpr.sim.native_loop`) against the Python loop, its reference.

* The square, the prototype's tour and the singularity crossing: the same log with the part on and off (the other
  parts native: the same kernels called one by one from Python) to round-off (1e-10 on q and v, 1e-10 relative to
  each array's size on the rest), and the Python paths' (every part off) states to 1e-9; the native loop ran
  almost every tick (the first and the last are the Python side's).
* Variants that change what a native tick computes: no observer, no momentum feedback, a heavier model, a
  constant wind, the take-off start, weaker rotors, other loop rates, an initial error; a run the watch stops
  (the same failure at the same time); a run where the force limiter acts (its outer updates handed back to
  Python, the ticks after them native again); progress reports every simulated second (handed back, the same
  reports); a reloaded robot and a copied plant.
* The switch: the loop runs only with its part and the parts it joins on; a robot kind without a compiled outer
  loop (the spatial FPR) says so.
"""

import copy
import dataclasses
import pickle

import numpy as np
import pytest
from native_parts import native_module, needs_native

import fpr
from controllers.authority import AuthoritySet
from controllers.ctc import CascadedController, ControllerSettings
from controllers.saturation import ForceLimiter
from fpr import _native as native
from fpr.sim import native_loop
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.plant import Plant
from planners.missions.mission import load_mission
from planners.optimize import plan

pytestmark = needs_native

FIELDS = ("q", "v", "speed", "speed_command", "thrust", "torque", "saturated", "closure_error", "drone_height",
          "attitude_desired", "disturbance")


@pytest.fixture(scope="module")
def square():
    return plan(load_mission("square"), "two-step")


@pytest.fixture(scope="module")
def tour():
    return plan(load_mission("prototype-tour"), "two-step")


@pytest.fixture(scope="module")
def crossing():
    return plan(load_mission("cross-singularity"), "two-step")


@pytest.fixture
def counted(monkeypatch):
    """The ticks the native loop did and its calls, counted."""
    counts = {"ticks": 0, "calls": 0}
    run = native_loop.NativeLoop.run

    def counting(self, k, *args):
        end = run(self, k, *args)
        counts["ticks"] += end - k
        counts["calls"] += 1
        return end

    monkeypatch.setattr(native_loop.NativeLoop, "run", counting)
    return counts


def _same(fast, reference, q_tol=1e-10, tol=1e-10):
    """The two logs equal to round-off: q and v within q_tol, the rest within tol times each array's size."""
    assert fast.failure == reference.failure and fast.failure_time == reference.failure_time
    np.testing.assert_array_equal(fast.t, reference.t)
    for name in FIELDS:
        a, b = getattr(fast, name), getattr(reference, name)
        assert a.shape == b.shape and a.dtype == b.dtype, name
        if name == "saturated":
            np.testing.assert_array_equal(a, b)
            continue
        atol = q_tol if name in ("q", "v") else tol * max(1.0, float(np.abs(b).max()) if b.size else 1.0)
        np.testing.assert_allclose(a, b, rtol=0, atol=atol, err_msg=name)


def _loop_off(result, settings, **more):
    with native.switched(**{"loop": False, **more}):
        return simulate(result, settings)


@pytest.mark.parametrize("mission", ["square", "tour", "crossing"])
def test_the_native_loop_is_the_python_loop(mission, request, counted):
    native_module("loop")
    result = request.getfixturevalue(mission)
    settings = SimulationSettings()
    fast = simulate(result, settings)
    ticks = fast.t.size
    assert fast.failure is None
    assert counted["ticks"] == ticks - 2  # all but the first (no outer-loop force yet) and the last
    _same(fast, _loop_off(result, settings))
    python = _loop_off(result, settings, **dict.fromkeys(native.PARTS, False))
    for name in ("q", "v"):  # the Python paths' states
        np.testing.assert_allclose(getattr(fast, name), getattr(python, name), rtol=0, atol=1e-9, err_msg=name)


VARIANTS = {
    "no observer": SimulationSettings(hold=0.3, controller=ControllerSettings(observer_bandwidth=0.0)),
    "no momentum feedback": SimulationSettings(hold=0.3, controller=ControllerSettings(momentum_feedback=False)),
    "heavier model": SimulationSettings(hold=0.3, model_mass_scale=1.1),
    "wind": SimulationSettings(hold=0.3, wind=(0.5, 1.0, -0.5)),
    "take-off": SimulationSettings(hold=0.3, takeoff=True),
    "weaker rotors": SimulationSettings(hold=0.3, rotor_constant_scale=0.9),
    "all three off": SimulationSettings(hold=0.3, controller=ControllerSettings(
        observer_bandwidth=0.0, momentum_feedback=False, force_limits=False)),
    "other rates": SimulationSettings(hold=0.3, plant_rate=2000.0, controller=ControllerSettings(
        inner_rate=250.0, outer_rate=50.0)),
    "initial error": SimulationSettings(hold=0.3, initial_error={"y": 0.05, "phi1": 0.1}),
}


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_variants_are_the_python_loop(variant, square, counted):
    settings = VARIANTS[variant]
    fast = simulate(square, settings)
    assert fast.failure is None and counted["ticks"] == fast.t.size - 2
    _same(fast, _loop_off(square, settings))


def test_a_prototype_variant_is_the_python_loop(tour, counted):
    settings = SimulationSettings(hold=0.0, rotor_constant_scale=0.9, model_mass_scale=1.1,
                                  controller=ControllerSettings(observer_bandwidth=0.0))
    fast = simulate(tour, settings)
    assert counted["ticks"] == fast.t.size - 2
    _same(fast, _loop_off(tour, settings))


def test_the_watch_stops_the_native_loop_as_the_python_one(square, counted):
    settings = SimulationSettings(max_tracking_error=0.002)
    fast = simulate(square, settings)
    assert fast.failure is not None and fast.failure.startswith("tracking lost")
    assert counted["ticks"] == fast.t.size - 2  # the failing tick is the Python side's (its check words it)
    _same(fast, _loop_off(square, settings))


def test_the_force_limiter_s_ticks_are_handed_back(monkeypatch, counted):
    fast_square = plan(load_mission("square").replace(times=[1.0] * 4), "none")  # asks w^2 < 0 at times
    settings = SimulationSettings(hold=0.0)
    calls = []
    limit = ForceLimiter.limit

    def counting(self, *args):
        calls.append(args[0] if args else None)
        return limit(self, *args)

    monkeypatch.setattr(ForceLimiter, "limit", counting)
    fast = simulate(fast_square, settings)
    assert calls  # the limiter ran (on the Python side)
    assert counted["calls"] > len(set(map(id, calls))) // 2 and counted["ticks"] > fast.t.size // 2
    held = []  # the times of the outer-loop updates whose forces the authority sets chose (controllers/authority.py)
    hold = AuthoritySet.hold

    def recording(self, q, v, wanted):
        out = hold(self, q, v, wanted)
        if self.limited:
            held.append(self.controller._clock)
        return out

    monkeypatch.setattr(AuthoritySet, "hold", recording)
    monkeypatch.setattr(CascadedController, "_clock", 0.0, raising=False)
    update = CascadedController.update

    def clocked(self, t, *args):
        self._clock = t
        return update(self, t, *args)

    monkeypatch.setattr(CascadedController, "update", clocked)
    reference = _loop_off(fast_square, settings)
    assert held  # on the Python side
    # the forces the sets choose come from SLSQP, accurate to its tolerance, and the run then diverges (a drone past
    # the vertical at 0.69 s): equal to round-off until the first such force, then to what that allows (the failure
    # itself the same)
    _same(fast, reference, q_tol=1e-6, tol=1e-6)
    early = fast.t < min(held)
    for log in (fast, reference):
        for name in FIELDS:
            setattr(log, name, getattr(log, name)[early])
        log.t = log.t[early]
    _same(fast, reference)


def test_progress_reports_are_handed_back(square, counted):
    settings = SimulationSettings(hold=0.2)
    reports, python_reports = [], []
    fast = simulate(square, settings, progress=lambda t, total: reports.append((t, total)))
    with native.switched(loop=False):
        reference = simulate(square, settings, progress=lambda t, total: python_reports.append((t, total)))
    assert reports == python_reports and len(reports) >= 10
    assert counted["calls"] == len(reports) + 2 and counted["ticks"] == fast.t.size - 2 - len(reports)
    _same(fast, reference)


def test_a_reloaded_robot_and_a_copied_plant(square, monkeypatch, counted):
    """The robot pickled and reloaded, the plant copied through its ``__getstate__`` (a plant does not pickle: its
    Pinocchio constraint models do not), both after their native objects were made: the copies make theirs again.
    """
    made = []
    original = Plant.from_minimal

    def copied(cls, *args, **kwargs):
        plant = original(*args, **kwargs)
        plant._step_kernel()  # its native objects made, then dropped by the copy
        twin = copy.copy(plant)
        assert twin._native_plant is None
        made.append(twin)
        return twin

    robot = square.robot
    robot.attitude_model(np.zeros(robot.nq) + 0.1, np.zeros(robot.nq))  # its native terms made
    reloaded = dataclasses.replace(square, robot=pickle.loads(pickle.dumps(robot)))
    assert "_native_minimal" not in reloaded.robot.__dict__
    monkeypatch.setattr(Plant, "from_minimal", classmethod(copied))
    settings = SimulationSettings(hold=0.2)
    fast = simulate(reloaded, settings)
    assert made and made[0]._native_plant is not None  # made again, and used
    assert counted["ticks"] == fast.t.size - 2
    monkeypatch.setattr(Plant, "from_minimal", original)
    _same(fast, _loop_off(square, settings))


def test_the_loop_runs_only_with_the_parts_it_joins(square, counted):
    settings = SimulationSettings(hold=0.0)
    for part in native_loop.JOINED_PARTS:
        with native.switched(**{part: False}):
            simulate(square, settings)
        assert counted["ticks"] == 0, part
    simulate(square, settings)
    assert counted["ticks"] > 0
    assert "loop" in native.PARTS and native.parts()["loop"]


def test_a_kind_without_a_compiled_outer_loop_says_so():
    spatial = fpr.load("fpr3")
    assert spatial.kind.compiled_outer_constants(ControllerSettings()) is None
    assert CascadedController(spatial).native_outer() is None
    for name in ("fpr", "prototype"):
        assert CascadedController(fpr.load(name)).native_outer() is not None


def test_an_update_whose_force_leaves_an_authority_set_is_handed_back(square, monkeypatch, counted):
    """An upward wind on the drones takes weight off them: the chain loop's forces leave the drones' authority sets at
    many outer-loop updates whose allocation has no rotor at a bound. The native loop hands each such update back to
    the Python side's AuthoritySet.hold (the same number of held forces as the Python loop) and does the others.
    """
    settings = SimulationSettings(wind=(0.0, 0.0, 6.0), hold=0.2)
    counts = []
    hold = AuthoritySet.hold

    def counting(self, q, v, wanted):
        out = hold(self, q, v, wanted)
        counts[-1] += self.limited
        return out

    monkeypatch.setattr(AuthoritySet, "hold", counting)
    counts.append(0)
    fast = simulate(square, settings)
    native_ticks = counted["ticks"]
    counts.append(0)
    reference = _loop_off(square, settings)
    assert fast.failure is None and counts[0] == counts[1] > 50
    assert native_ticks > fast.t.size // 2  # the other updates and ticks native
    _same(fast, reference, q_tol=1e-6, tol=1e-5)  # the held forces come from SLSQP, accurate to its tolerance
