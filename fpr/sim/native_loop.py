"""The closed loop's plain ticks natively (:mod:`fpr._native`'s part ``loop``, ``fpr/_native/cpp/loop.cpp``).

:func:`fpr.sim.closed_loop.simulate` hands the ticks between two outer-loop updates to one native call, which
runs them without the interpreter: the plant's points and closure error, the measurement, the watch's screen,
the inner loop, the attitude model with the observer's estimate, the allocation, the rotor speeds, the
observer's sum of the applied forces, the log's row and the plant's steps, each by the same kernel as the part
that computes it alone (the same computation as the Python paths, equal to round-off:
``tests/test_loop_compiled.py``). A tick it does not do (an outer-loop update, a watch screen that fires, a
kernel that declines, plant steps that fail, a progress report) it hands back: the Python side does that tick
with its own code on the same state (the plant's state, the measurement's reference, the controller's held
force, observer estimate and sum of applied forces, the allocator's active bounds), then hands the next ticks
back to the native loop.

It runs when the part ``loop`` and the parts it joins (``plant``, ``measure``, ``attitude``, ``allocation``,
``inner``, ``watch``) are on and built, for a simulation without events or replanning (``in_flight``) and without
measurement noise, on a plant whose forces the native steps compute, with a controller whose robot kind's inner
loop is compiled (``compiled_inner_constants``) and whose drones' attitudes are their rolls.
"""

from __future__ import annotations

import numpy as np

from fpr import _native as native
from fpr.model.constrained import _minimal_cache
from fpr.sim.plant import Plant

#: the parts the native loop joins: it runs only when each of them runs native
JOINED_PARTS = ("loop", "plant", "measure", "attitude", "allocation", "inner", "watch")

#: the log's arrays the native loop writes, in its order: (name, shape of one row, dtype)
_LOG_FIELDS = ("q", "v", "speed", "closure_error", "drone_height", "attitude_desired", "speed_command", "thrust",
               "torque", "saturated", "disturbance")


class NativeLoop:
    """The native loop of one simulation and the log's preallocated arrays (both paths write them: row k at tick k).

    Build it with :meth:`make` (None when the simulation does not fit the native loop).

    Attributes:
        logs: the log's arrays by name (:data:`_LOG_FIELDS`), n_t rows each.
    """

    def __init__(self, loop, plant, controller, logs, threshold: float):
        self._loop = loop
        self._plant = plant
        self._controller = controller
        self.logs = logs
        self._threshold = threshold
        self._observer = controller.settings.observer_bandwidth > 0
        self._spare = np.zeros(controller.robot.nq)  # the applied sum's stand-in without an observer

    @classmethod
    def make(cls, plant, controller, watch, ticks, motion, thrust_vectors, rate, acceleration, dt: float, steps: int,
             wind) -> "NativeLoop | None":
        """The native loop of a simulation, or None when it does not fit (module docstring).

        Args:
            plant: the :class:`~fpr.sim.plant.Plant`.
            controller: the :class:`controllers.ctc.CascadedController`.
            watch: the :class:`fpr.sim.watch.Watch`.
            ticks: the inner-loop ticks' times (n_t,) [s].
            motion: the plan's s_d and its derivatives at the ticks (>= 5, n_t, n_s).
            thrust_vectors: the plan's thrust vectors at the ticks (n_t, n_d, 2) [N].
            rate: the planned attitude rates at the ticks (n_t, n_d) [rad/s].
            acceleration: the planned attitude accelerations at the ticks (n_t, n_d) [rad/s^2].
            dt: the plant's step [s].
            steps: plant steps per tick.
            wind: the wind on each drone (3,) [N], or None.
        """
        if not all(native.parts()[part] for part in JOINED_PARTS):
            return None
        module = native.use("loop")
        robot = controller.robot
        if type(plant) is not Plant or not plant._compiles_forces() or not plant._closure_is_3d:
            return None
        kernel = plant._step_kernel()
        measure = _minimal_cache(plant.closed).native_measure(plant.closed)
        constants = robot.__dict__.get("_attitude_constants") or robot._build_attitude_constants()
        terms = robot._native_terms()
        inner = controller._inner_kernel()
        allocator = controller.allocator
        n_d, n_rolls = robot.n_drones, len(robot.layout.rolls)
        if (kernel is None or measure is None or constants[-1] is None or terms is None or inner is None
                or not allocator.compiled or n_rolls != n_d or plant._reference is None
                or np.shape(thrust_vectors)[1:] != (n_d, 2)):
            return None
        watch._build_screen(plant)
        outer = controller.native_outer()  # None: the outer-loop updates are the Python side's
        n_t, n, n_s = ticks.size, robot.nq, len(controller.chain)
        shapes = {"q": (n,), "v": (n,), "speed": (n_d, 4), "closure_error": (), "drone_height": (n_d,),
                  "attitude_desired": (n_d,), "speed_command": (n_d, 4), "thrust": (n_d,), "torque": (n_d, 3),
                  "saturated": (n_d, 4), "disturbance": (n_s,)}
        logs = {name: np.zeros((n_t,) + shapes[name], dtype=bool if name == "saturated" else float)
                for name in _LOG_FIELDS}
        decay = plant._lean_constants(dt)[0].reshape(-1)
        wind_forces = None if wind is None else np.ascontiguousarray(plant._wind_forces(wind), dtype=float)
        controller._attitude_gains()  # the inner loop's constants up to date, in controller._gains
        st = controller.settings
        loop = module.Loop(kernel, measure, terms, None if outer is None else outer[0], allocator._kernel_constants,
                           allocator._state, controller._gains[5], constants[-1], watch._screen_constants,
                           None if outer is None else outer[1], np.ascontiguousarray(ticks, dtype=float),
                           np.ascontiguousarray(np.asarray(motion)[:5].transpose(1, 0, 2), dtype=float),
                           np.ascontiguousarray(thrust_vectors, dtype=float), np.ascontiguousarray(rate, dtype=float),
                           np.ascontiguousarray(acceleration, dtype=float), controller.chain.tolist(),
                           tuple(logs[name] for name in _LOG_FIELDS), float(dt), int(steps), float(plant._max_speed),
                           np.ascontiguousarray(decay, dtype=float), wind_forces, st.observer_bandwidth > 0,
                           bool(st.force_limits),
                           controller.limiter.authority.compiled_constants() if st.force_limits else None)
        threshold = 1.0 / st.outer_rate - 1e-9  # CascadedController.update's test
        return cls(loop, plant, controller, logs, threshold)

    def run(self, k: int, stop: int, report_at: float, tick: float) -> int:
        """The ticks k, k + 1, ... before ``stop`` natively, until one the Python side must do; its index.

        The controller's state the native loop reads and writes is handed over as arrays the controller (and its
        observer) then hold, so that the Python side reads what the native ticks left, and the other way round.

        Args:
            k: the first tick.
            stop: the tick the native loop does not reach (the last tick is the Python side's).
            report_at: the time of the next progress report [s] (inf: none); the tick t with t + tick >= report_at
                is the Python side's.
            tick: the inner-loop period [s] (the simulation's, as it computes the reports' times).
        """
        c, plant = self._controller, self._plant
        if c._force is None or k >= stop:
            return k
        qc, vc, w = plant.qc.copy(), plant.vc.copy(), np.array(plant._w, dtype=float)
        reference = plant._reference.copy()
        c._integral = integral = np.array(c._integral, dtype=float)
        c._force = force = np.array(c._force, dtype=float)
        observed = (None,) * 6
        applied = self._spare
        if self._observer:
            o = c.observer
            if o is None or o._start is None or o._last is None:  # before its first update: the Python side's
                return k
            o.estimate, o._start, o._integral = (np.array(x, dtype=float) for x in (o.estimate, o._start, o._integral))
            o._last = tuple(np.array(x, dtype=float) for x in o._last)
            observed = (o.estimate, o._start, o._integral) + o._last
            c._applied = applied = np.array(c._applied, dtype=float)
        end, time, ticks, last_outer, limited, closed_form, active_set = self._loop.run(
            k, stop, qc, vc, w, reference, integral, *observed, force, applied, int(c._ticks), plant.time,
            float(c._last_outer), bool(c.limiter.limited), self._threshold, report_at, tick)
        if end > k:  # the native ticks' state back where the Python side reads it
            plant.qc, plant.vc, plant._w, plant._reference, plant.time = qc, vc, w, reference, time
            c._ticks, c._last_outer, c.limiter.limited = ticks, last_outer, limited
            routes = c.allocator.routes
            routes["closed form"] += closed_form
            routes["active set"] += active_set
        return end

    def log_measured(self, k: int, q, v, speed, closure_error: float, positions) -> None:
        """Row k of the measured arrays, from a tick the Python side did."""
        logs = self.logs
        logs["q"][k], logs["v"][k], logs["speed"][k] = q, v, speed
        logs["closure_error"][k] = closure_error
        logs["drone_height"][k] = np.asarray(positions)[:, 2]

    def log_commanded(self, k: int, attitude_target, speeds, thrust, torque, saturated, disturbance) -> None:
        """Row k of the controller's arrays, from a tick the Python side did."""
        logs = self.logs
        logs["attitude_desired"][k], logs["speed_command"][k], logs["thrust"][k] = attitude_target, speeds, thrust
        logs["torque"][k], logs["saturated"][k], logs["disturbance"][k] = torque, saturated, disturbance

    def stacked(self, rows: int) -> dict:
        """The log's arrays of the first ``rows`` ticks (copies)."""
        return {name: array[:rows].copy() for name, array in self.logs.items()}


__all__ = ["JOINED_PARTS", "NativeLoop"]
