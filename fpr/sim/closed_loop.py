"""Closed-loop simulation of a planned motion: the cascaded CTC on the faithful plant.

Plant: :class:`fpr.sim.plant.Plant`, the drones as free-flying quadrotors closed by the chain
(Pinocchio constraint dynamics, Lie-group RK4 at ``plant_rate``), rotors saturated to
[0, w_max] with a first-order motor lag. Controller: :class:`controllers.ctc.CascadedController`
(outer loop at ``outer_rate``, inner loop and allocation at ``inner_rate``), fed with the state
measured from the plant (minimal coordinates, optional Gaussian noise) and the plan sampled at
its ticks. Optional: an initial state error, a controller model with other masses than the plant,
rotor constants off by a factor, a constant wind force on each drone.

A lost robot is a result: at every inner-loop tick :class:`fpr.sim.watch.Watch` checks the state (a drone
below the ground, the closure broken, a diverging or non-finite state, a tracking error past a bound, all
bounds in :class:`SimulationSettings`). When one fires the simulation stops there and returns the log of
what was simulated, its ``failure`` saying what happened and when; a state that turns non-finite
(:class:`fpr.sim.plant.PlantDivergedError`) ends the same way.

The ticks run natively when they fit (:mod:`fpr.sim.native_loop`, :mod:`fpr._native`'s part ``loop``: the same
computation in C++, equal to round-off), the unusual ones (events, noise, a watch that fires, the force limiter,
progress reports) handed back to the Python loop below, which is their reference.

The :class:`SimulationLog` holds, at every inner-loop tick, what the thesis plots (Fig 3.19-3.32,
3.42-3.51): the full state, the reference, the rotor speeds commanded and obtained, thrusts,
torques, desired rolls, saturation flags and the closure error; :meth:`SimulationLog.summary`
condenses it and :meth:`SimulationLog.save` writes it (``.npz``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from controllers.ctc import CascadedController, ControllerSettings, Reference
from fpr.model.errors import ModelArgumentError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.robots import get, load
from fpr.sim.native_loop import NativeLoop
from fpr.sim.plant import Plant, PlantDivergedError
from fpr.sim.watch import Watch


@dataclass
class SimulationSettings:
    """What to simulate besides the plan.

    Attributes:
        plant_rate: integration rate of the plant [Hz].
        controller: gains and loop rates (:class:`controllers.ctc.ControllerSettings`).
        hold: time simulated after the end of the plan, holding its last point [s].
        initial_error: offsets added to the initial state, by coordinate name, e.g. {"y": 0.05} [m, rad].
        model_mass_scale: the controller's model has every mass (drones, links, end-effector)
            multiplied by this (1.1: the controller believes the robot 10 % heavier than it is).
        rotor_constant_scale: the plant's rotors produce this times the nominal force and drag, >= 0
            (0: no thrust); the controller does not know it. The rotors start at the planned speeds.
        measurement_noise: standard deviations of the noise on the measured (q, v) [m or rad, per s].
        wind: constant force on each drone's centre, world frame (x, y, z) [N].
        seed: noise seed.
        takeoff: start at rest on the take-off pose, as the thesis' drones did (seed 3.3.2, Fig. 3.50): every
            drone level (roll 0) instead of at its planned roll, its four rotors at one speed giving the
            planned thrust (no torque); False: start on the plan (planned rolls and rotor speeds).

    Bounds of the watch for a lost robot (:mod:`fpr.sim.watch`); the reference missions (square,
    prototype tour, singularity crossing) stay far inside them:

    Attributes:
        ground_tolerance: a drone's hinge or centre of mass lower than ``robot.kind.ground_height`` by more
            than this is below the ground [m] (default 0.05; the plans keep the hinges m_gd = 0.1 m above).
        max_closure_error: loop-closure error of the plant that means the chain broke [m] (default 1e-3;
            the reference missions stay below 1e-6).
        max_drone_speed: speed of a drone's hinge past which the state diverged [m/s] (default 30).
        max_drone_rate: angular speed of a drone past which the state diverged [rad/s] (default 60).
        max_tilt: angle of a drone's thrust axis from the vertical past which it is lost [rad] (default pi/2:
            the thrust pushes it down).
        max_tracking_error: ``|measured - planned|`` of each planning coordinate past which tracking is lost
            [m or rad, the coordinate's unit] (default 1; the reference missions stay below 0.01).
    """

    plant_rate: float = 1000.0
    controller: ControllerSettings = field(default_factory=ControllerSettings)
    hold: float = 1.0
    initial_error: dict = field(default_factory=dict)
    model_mass_scale: float = 1.0
    rotor_constant_scale: float = 1.0
    measurement_noise: tuple[float, float] = (0.0, 0.0)
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    seed: int = 0
    takeoff: bool = False
    ground_tolerance: float = 0.05
    max_closure_error: float = 1e-3
    max_drone_speed: float = 30.0
    max_drone_rate: float = 60.0
    max_tilt: float = math.pi / 2
    max_tracking_error: float = 1.0


@dataclass(eq=False)
class SimulationLog:
    """Everything recorded at the inner-loop ticks (N samples).

    Attributes:
        robot_name: the robot's registry name (``robot.name``: "fpr", "prototype"...).
        coordinates: names of the columns of q and v.
        chain: names of the planning coordinates (columns of reference).
        t: times (N,) [s].
        q, v: plant state in thesis coordinates (N, n) [m, rad; /s].
        reference: planned s and its first two derivatives (3, N, n_s).
        planned_attitude: the plan's drone attitudes (``layout.drone_attitude`` flattened; a planar robot's
            rolls) (N, n_d k_a) [rad]; ``planned_roll`` is its former name (a read-only alias, and its key in the
            files of :meth:`save`).
        attitude_desired: the controller's targets of the same coordinates (its ``attitude_target``: the
            desired rolls) (N, n_d k_a) [rad]; ``roll_desired`` is its former name (alias and file key).
        speed_command: allocated rotor speeds (N, n_d, 4) [rad/s].
        speed: plant rotor speeds (after lag and saturation) (N, n_d, 4) [rad/s].
        thrust, torque: allocated thrusts (N, n_d) [N] and torques (N, n_d, 3) [N m].
        saturated: rotors at a bound in the allocation (N, n_d, 4).
        drone_height: z of each drone's centre of mass in the plant (N, n_d) [m].
        closure_error: loop-closure error of the plant (N,) [m].
        max_speed: w_max [rad/s]; speed_limit: w_max - m_gr, the planning limit [rad/s].
        wall_time: simulation wall time [s].
        failure: None when the simulation ran to its end; else one line saying how the robot was lost, which
            drone or coordinate, the value, the bound and when (:mod:`fpr.sim.watch`), e.g. "drone 2 hinge
            below the ground (z = -0.8061 m < -0.8 m: ground -0.75 m, tolerance 0.05 m) at t = 0.522 s".
            The arrays then stop at that tick (their last sample is at ``failure_time``), or, when the state
            turned non-finite, at the last finite sample, just before ``failure_time``.
        failure_time: simulated time of the failure [s], or None.
        disturbance: the controller's estimate of the external generalised force on the chain at each tick
            (:attr:`controllers.ctc.CascadedController.disturbance`, zeros without its observer) (N, n_s)
            [N or N m], or None (a log saved before it was recorded).
    """

    robot_name: str
    coordinates: tuple
    chain: tuple
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    reference: np.ndarray
    planned_attitude: np.ndarray
    attitude_desired: np.ndarray
    speed_command: np.ndarray
    speed: np.ndarray
    thrust: np.ndarray
    torque: np.ndarray
    saturated: np.ndarray
    drone_height: np.ndarray
    closure_error: np.ndarray
    max_speed: float
    speed_limit: float
    wall_time: float
    failure: str | None = None
    failure_time: float | None = None
    disturbance: np.ndarray | None = None

    @property
    def planned_roll(self) -> np.ndarray:
        """``planned_attitude`` under its former name (a planar robot's planned rolls)."""
        return self.planned_attitude

    @property
    def roll_desired(self) -> np.ndarray:
        """``attitude_desired`` under its former name (a planar robot's desired rolls)."""
        return self.attitude_desired

    def column(self, name: str) -> np.ndarray:
        """The measured coordinate ``name`` over time."""
        return self.q[:, self.coordinates.index(name)]

    @property
    def tracking_error(self) -> np.ndarray:
        """Measured minus planned planning coordinates (N, n_s)."""
        idx = [self.coordinates.index(c) for c in self.chain]
        return self.q[:, idx] - self.reference[0]

    @property
    def real_time_factor(self) -> float:
        """Simulated time per wall-clock time."""
        return float(self.t[-1] - self.t[0]) / max(self.wall_time, 1e-12)

    def summary(self) -> dict:
        """Tracking errors (RMS and max per planning coordinate), out-of-plane motion (the robot kind's
        ``out_of_plane`` coordinates), rotor speeds
        against the limits, allocation saturations, closure error, real-time factor, and the failure (None
        for a run that reached its end) with its time.
        """
        err = self.tracking_error
        out = {
            "tracking_rms": {c: float(np.sqrt(np.mean(err[:, i] ** 2))) for i, c in enumerate(self.chain)},
            "tracking_max": {c: float(np.abs(err[:, i]).max()) for i, c in enumerate(self.chain)},
            "final_error": {c: float(err[-1, i]) for i, c in enumerate(self.chain)},
            "max_abs_out_of_plane": {c: float(np.abs(self.column(c)).max())
                                     for c in get(self.robot_name).out_of_plane if c in self.coordinates},
            "peak_rotor_speed_rad_s": float(self.speed.max()),
            "least_rotor_speed_rad_s": float(self.speed.min()),
            "rotor_speed_limit_rad_s": self.max_speed,
            "planning_speed_limit_rad_s": self.speed_limit,
            "saturated_ticks": int(self.saturated.any(axis=(1, 2)).sum()),
            "ticks": int(self.t.size),
            "least_drone_height_m": float(self.drone_height.min()),
            "max_closure_error_m": float(self.closure_error.max()),
            "simulated_s": float(self.t[-1] - self.t[0]),
            "wall_time_s": self.wall_time,
            "real_time_factor": self.real_time_factor,
            "failure": self.failure,
            "failure_time_s": self.failure_time,
        }
        return out

    def save(self, path) -> None:
        """Write every array and the scalars to a NumPy ``.npz`` file (no failure: ``failure`` is stored as
        an empty string and ``failure_time`` as NaN). The drones' attitudes keep their former keys
        (``planned_roll``, ``roll_desired``: the files of every version read alike).
        """
        arrays = {_FILE_KEYS.get(k, k): v for k, v in vars(self).items() if isinstance(v, np.ndarray)}
        np.savez_compressed(path, robot_name=self.robot_name, coordinates=np.array(self.coordinates),
                            chain=np.array(self.chain), max_speed=self.max_speed, speed_limit=self.speed_limit,
                            wall_time=self.wall_time, failure=np.array(self.failure or ""),
                            failure_time=np.nan if self.failure_time is None else self.failure_time, **arrays)

    @classmethod
    def load(cls, path) -> "SimulationLog":
        """Read a log written by :meth:`save` (one written before the failure fields: no failure)."""
        with np.load(path) as data:
            values = {_FIELDS.get(k, k): data[k] for k in data.files}
        failure = str(values.pop("failure", "")) or None
        failure_time = float(values.pop("failure_time", np.nan))
        values["failure"], values["failure_time"] = failure, None if np.isnan(failure_time) else failure_time
        return cls(robot_name=str(values.pop("robot_name")), coordinates=tuple(values.pop("coordinates").tolist()),
                   chain=tuple(values.pop("chain").tolist()), max_speed=float(values.pop("max_speed")),
                   speed_limit=float(values.pop("speed_limit")), wall_time=float(values.pop("wall_time")), **values)


def _drone_attitudes(planned) -> np.ndarray:
    """The plan's drone attitude coordinates, drone after drone, shape (N, n_d k_a) [rad]."""
    return planned.attitude.reshape(planned.attitude.shape[0], -1)


def _attitude_feedforward(planned) -> tuple[np.ndarray, np.ndarray]:
    """The plan's rates and accelerations of the drones' attitude coordinates, drone after drone, each of shape
    (N, n_d k_a): the controller's feed-forward (``Reference.attitude_rate``, ``attitude_acceleration``).
    """
    n = planned.attitude_rate.shape[0]
    return planned.attitude_rate.reshape(n, -1), planned.attitude_acceleration.reshape(n, -1)


#: The file keys of :meth:`SimulationLog.save` that differ from the fields' names, and back.
_FILE_KEYS = {"planned_attitude": "planned_roll", "attitude_desired": "roll_desired"}
_FIELDS = {v: k for k, v in _FILE_KEYS.items()}


def _scaled_robot(robot, scale: float):
    """The same robot with every mass (the kind's ``mass_parameters``) multiplied by ``scale`` (a
    controller's wrong belief).
    """
    if scale == 1.0:
        return robot
    overrides = {k: robot.parameters[k] * scale for k in robot.kind.mass_parameters}
    return load(robot.name, **overrides)


def _positive(name, value, zero_ok=False) -> None:
    """Refuse a setting that is not a finite number > 0 (>= 0 with ``zero_ok``)."""
    try:
        ok = bool(np.isfinite(value) and (value >= 0 if zero_ok else value > 0))
    except TypeError:
        ok = False
    if not ok:
        raise ModelArgumentError(name, value, f"{name} = {value!r}: give a finite number "
                                              f"{'>= 0' if zero_ok else '> 0'}")


def _check_settings(st: SimulationSettings, robot) -> None:
    """Refuse settings that cannot describe a simulation (the message names the field and what to give)."""
    _positive("plant_rate", st.plant_rate)
    _positive("hold", st.hold, zero_ok=True)
    _positive("model_mass_scale", st.model_mass_scale)
    _positive("rotor_constant_scale", st.rotor_constant_scale, zero_ok=True)
    for name in ("ground_tolerance", "max_closure_error", "max_drone_speed", "max_drone_rate", "max_tilt",
                 "max_tracking_error"):
        _positive(name, getattr(st, name))
    noise = np.asarray(st.measurement_noise, dtype=object)
    if noise.shape != (2,):
        raise ModelArgumentError("measurement_noise", st.measurement_noise,
                                 f"measurement_noise = {st.measurement_noise!r}: give two standard "
                                 "deviations (q [m or rad], v [m/s or rad/s]), each >= 0")
    for value in noise:
        _positive("measurement_noise", value, zero_ok=True)
    wind = np.asarray(st.wind, dtype=object)
    if wind.shape != (3,) or not all(isinstance(f, (int, float, np.number)) and np.isfinite(f) for f in wind):
        raise ModelArgumentError("wind", st.wind,
                                 f"wind = {st.wind!r}: give three finite forces (x, y, z) [N]")
    for name, offset in st.initial_error.items():
        if name not in robot.index:
            raise ModelArgumentError("initial_error", name,
                                     f"initial_error: unknown coordinate {name!r}; use one of {', '.join(robot.index)}")
        if not isinstance(offset, (int, float, np.number)) or not np.isfinite(offset):
            raise ModelArgumentError("initial_error", offset,
                                     f"initial_error {name} = {offset!r}: give a finite number [m or rad]")


def simulate(result, settings: SimulationSettings | None = None, progress=None,
             in_flight=None) -> SimulationLog:
    """Track the planned motion of ``result`` in closed loop, until its end or until the robot is lost.

    Args:
        result: a :class:`planners.optimize.PlanResult` (its ``trajectory`` and ``robot``).
        settings: :class:`SimulationSettings`.
        progress: called as ``progress(simulated_time, total_time)`` about every simulated second.
        in_flight: events and replanning (:class:`fpr.sim.replanning.InFlight`): its ``make_plant`` builds the
            plant (gusts), its ``after_tick(t, q, v, reference)`` may return a new plan in force, tracked from
            the next tick on (the log's reference is then the plan in force at each tick); its
            ``known_force(t)`` is the wind the controller knows, fed forward, and ``inputs`` the plan's
            inputs flown in it (the roll feed-forward); its ``attach(controller)``, when it has one, is given
            the controller (its observer's estimate of the wind). None: neither.

    Returns:
        the :class:`SimulationLog`; when the robot is lost (:mod:`fpr.sim.watch`, or a state that turns
        non-finite) it stops there, with ``failure`` and ``failure_time`` set.

    Raises:
        ModelArgumentError: rates that are not integer multiples of each other, an initial error on
            an unknown coordinate, a setting that is not a finite number in its range (a scale or a bound
            <= 0, a negative noise or hold, a wind that is not three forces).
    """
    st = settings or SimulationSettings()
    robot = result.robot
    _check_settings(st, robot)
    ctrl_settings = st.controller
    steps_per_tick = st.plant_rate / ctrl_settings.inner_rate
    if abs(steps_per_tick - round(steps_per_tick)) > 1e-9 or steps_per_tick < 1:
        raise ModelArgumentError("plant_rate", st.plant_rate,
                                 f"plant_rate {st.plant_rate:g} Hz must be an integer multiple of the inner-loop "
                                 f"rate {ctrl_settings.inner_rate:g} Hz")
    steps_per_tick = int(round(steps_per_tick))
    dt = 1.0 / st.plant_rate
    tick = steps_per_tick * dt
    trajectory = result.trajectory
    total = trajectory.total_duration + st.hold
    ticks = np.arange(int(np.floor(total / tick + 1e-9)) + 1) * tick
    motion = trajectory.evaluate_held(ticks, order=MOTION_ORDER)  # at rest after the end
    # the plan's inputs (roll feed-forward), flown in the wind the controller knows (fpr.sim.replanning)
    planned = inverse_dynamics(robot, motion) if in_flight is None else in_flight.inputs(robot, ticks, motion)
    q_plan = planned.full_state(robot)[0]
    planned_rate, planned_acceleration = _attitude_feedforward(planned)

    controller = CascadedController(_scaled_robot(robot, st.model_mass_scale), ctrl_settings)
    if in_flight is not None and hasattr(in_flight, "attach"):
        in_flight.attach(controller)
    q0 = q_plan[0].copy()
    for name, offset in st.initial_error.items():
        q0[robot.index[name]] += offset
    w0 = planned.rotor_speed[0]
    if st.takeoff:  # at rest on the take-off pose: drones level, rotors at one speed each
        q0 = robot.kind.level_attitude(q0)
        w0 = np.repeat(np.sqrt(np.mean(planned.rotor_speed_squared[0], axis=-1, keepdims=True)), 4, axis=-1)
    make_plant = Plant.from_minimal if in_flight is None else in_flight.make_plant
    plant = make_plant(robot, q0, np.zeros(robot.nq), w0, rotor_constant_scale=st.rotor_constant_scale)
    watch = Watch(robot, st)
    rng = np.random.default_rng(st.seed)
    noise_q, noise_v = st.measurement_noise
    wind = np.asarray(st.wind, dtype=float)
    wind = None if not wind.any() else wind

    n, n_d, n_t = robot.nq, robot.n_drones, ticks.size
    n_a = len(robot.layout.rolls)  # the drones' attitude coordinates (layout.drone_attitude flattened)
    # the log: each tick's arrays kept as they are (fresh arrays, or read-only ones), stacked after the loop (one
    # list append per group instead of a numpy row write per array)
    measured, commanded = [], []  # (q, v, rotor speeds, closure error, centres); (rolls, command, f, tau, saturated)
    # the plain ticks natively when they fit (fpr.sim.native_loop): the log then in its preallocated arrays
    fast = None
    if in_flight is None and not noise_q and not noise_v:
        fast = NativeLoop.make(plant, controller, watch, ticks, motion, planned.thrust_vector, planned_rate,
                               planned_acceleration, dt, steps_per_tick, wind)
    start = time.perf_counter()
    next_report = 1.0
    failure = failure_time = None
    last = n_t - 1  # index of the last logged tick
    # the loop's lookups done once (every tick pays for each attribute or dict access); the times as floats
    # (the same values; float arithmetic is cheaper than numpy scalars')
    log_measured, log_commanded = measured.append, commanded.append
    observe, check, update, advance = plant.observe, watch.check, controller.update, plant.advance
    times = ticks.tolist()
    k = 0
    while k < n_t:
        if fast is not None:  # the native loop's ticks, up to one the Python side must do
            k = fast.run(k, n_t - 1, next_report if progress is not None else math.inf, tick)
        t = times[k]
        q, v, positions, closure_error = observe()  # one kinematics pass
        failure = check(t, plant, q, v, positions, closure_error, motion[0, k])
        if failure is not None and not (np.isfinite(q).all() and np.isfinite(v).all()):
            last, failure_time = k - 1, float(t)  # nothing finite to log at this tick
            break
        if fast is None:
            log_measured((q, v, plant.rotor_speeds, closure_error, positions))
        else:
            fast.log_measured(k, q, v, plant.rotor_speeds, closure_error, positions)
        q_meas = q + noise_q * rng.normal(size=n) if noise_q else q
        v_meas = v + noise_v * rng.normal(size=n) if noise_v else v
        reference = Reference(motion[:5, k], planned_rate[k], planned_acceleration[k], planned.thrust_vector[k])
        if in_flight is not None:  # a wind the controller knows, fed forward (None: none)
            reference.task_force, reference.drone_forces = in_flight.known_force(float(t))
        out = update(t, q_meas, v_meas, reference)
        allocation = out.allocation
        row = (out.attitude_target, out.speeds, allocation.thrust, allocation.torque, allocation.saturated,
               controller.disturbance)
        if fast is None:
            log_commanded(row)
        else:
            fast.log_commanded(k, *row)
        if failure is not None:
            last, failure_time = k, float(t)
            break
        if k == n_t - 1:
            break
        if in_flight is not None:  # replanning (fpr.sim.replanning): a new plan in force from the next tick
            new = in_flight.after_tick(float(t), q, v, motion[:5, k])
            if new is not None:
                motion = new.evaluate_held(ticks, order=MOTION_ORDER)
            if new is not None or in_flight.known_changed:
                planned = in_flight.inputs(robot, ticks, motion)
                planned_rate, planned_acceleration = _attitude_feedforward(planned)
        try:  # the command as the controller gave it: the plant saturates it to [0, w_max]
            advance(out.speeds, dt, steps_per_tick, wind)
        except PlantDivergedError as error:  # the plant keeps its last finite state
            last, failure_time = k, error.time + dt
            failure = (f"the state diverged ({error.what}) between t = {error.time:.4f} s "
                       f"and {failure_time:.4f} s")
            break
        if progress is not None and t + tick >= next_report:
            progress(t + tick, ticks[-1])
            next_report += 1.0
        k += 1
    keep = slice(0, last + 1)
    log = {}  # the groups stacked: both hold last + 1 ticks
    for rows, fields in ((measured, {"q": (n,), "v": (n,), "speed": (n_d, 4), "closure_error": (),
                                     "positions": (n_d, 3)}),
                         (commanded, {"attitude_desired": (n_a,), "speed_command": (n_d, 4), "thrust": (n_d,),
                                      "torque": (n_d, 3), "saturated": (n_d, 4),
                                      "disturbance": (len(robot.layout.chain),)})):
        columns = zip(*rows, strict=True) if rows else [()] * len(fields)
        for (name, shape), column in zip(fields.items(), columns, strict=True):
            dtype = bool if name == "saturated" else float
            log[name] = np.array(column, dtype=dtype).reshape((len(rows),) + shape)
    if fast is None:
        log["drone_height"] = log.pop("positions")[:, :, 2].copy()
    else:  # the native loop's arrays: as many rows as the lists would hold
        log = fast.stacked(last + 1)
    speed_limit = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    return SimulationLog(robot.name, tuple(robot.layout.coordinates), tuple(robot.layout.chain), ticks[keep],
                         log["q"], log["v"], motion[:3, keep], _drone_attitudes(planned)[keep], log["attitude_desired"],
                         log["speed_command"], log["speed"], log["thrust"], log["torque"],
                         log["saturated"], log["drone_height"], log["closure_error"],
                         robot.rotor_constants.max_speed, speed_limit, time.perf_counter() - start, failure,
                         failure_time, log["disturbance"])
