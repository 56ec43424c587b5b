"""Closed-loop simulation of a planned motion: the cascaded CTC on the faithful plant.

Plant: :class:`fpr.sim.plant.Plant`, the drones as free-flying quadrotors closed by the chain
(Pinocchio constraint dynamics, Lie-group RK4 at ``plant_rate``), rotors saturated to
[0, w_max] with a first-order motor lag. Controller: :class:`controllers.ctc.CascadedController`
(outer loop at ``outer_rate``, inner loop and allocation at ``inner_rate``), fed with the state
measured from the plant (minimal coordinates, optional Gaussian noise) and the plan sampled at
its ticks. Optional: an initial state error, a controller model with other masses than the plant,
rotor constants off by a factor, a constant wind force on each drone.

The :class:`SimulationLog` holds, at every inner-loop tick, what the thesis plots (Fig 3.19-3.32,
3.42-3.51): the full state, the reference, the rotor speeds commanded and obtained, thrusts,
torques, desired rolls, saturation flags and the closure error; :meth:`SimulationLog.summary`
condenses it and :meth:`SimulationLog.save` writes it (``.npz``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from controllers.ctc import CascadedController, ControllerSettings, Reference
from fpr.model.errors import ModelArgumentError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.robots import load
from fpr.sim.plant import Plant


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
        rotor_constant_scale: the plant's rotors produce this times the nominal force and drag
            (emulated by running the plant's nominal rotors sqrt(scale) times faster; the log shows
            the real rotors' speeds).
        measurement_noise: standard deviations of the noise on the measured (q, v) [m or rad, per s].
        wind: constant force on each drone's centre, world frame (x, y, z) [N].
        seed: noise seed.
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
        planned_roll: the plan's drone rolls (N, n_d) [rad].
        roll_desired: the outer loop's desired rolls (N, n_d) [rad].
        speed_command: allocated rotor speeds (N, n_d, 4) [rad/s].
        speed: plant rotor speeds (after lag and saturation) (N, n_d, 4) [rad/s].
        thrust, torque: allocated thrusts (N, n_d) [N] and torques (N, n_d, 3) [N m].
        saturated: rotors at a bound in the allocation (N, n_d, 4).
        drone_height: z of each drone's centre of mass in the plant (N, n_d) [m].
        closure_error: loop-closure error of the plant (N,) [m].
        max_speed: w_max [rad/s]; speed_limit: w_max - m_gr, the planning limit [rad/s].
        wall_time: simulation wall time [s].
    """

    robot_name: str
    coordinates: tuple
    chain: tuple
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    reference: np.ndarray
    planned_roll: np.ndarray
    roll_desired: np.ndarray
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
        """Tracking errors (RMS and max per planning coordinate), out-of-plane motion, rotor speeds
        against the limits, allocation saturations, closure error, real-time factor."""
        err = self.tracking_error
        out = {
            "tracking_rms": {c: float(np.sqrt(np.mean(err[:, i] ** 2))) for i, c in enumerate(self.chain)},
            "tracking_max": {c: float(np.abs(err[:, i]).max()) for i, c in enumerate(self.chain)},
            "final_error": {c: float(err[-1, i]) for i, c in enumerate(self.chain)},
            "max_abs_out_of_plane": {c: float(np.abs(self.column(c)).max())
                                     for c in ("x", "psi", "theta") if c in self.coordinates},
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
        }
        return out

    def save(self, path) -> None:
        """Write every array and the scalars to a NumPy ``.npz`` file."""
        arrays = {k: v for k, v in vars(self).items() if isinstance(v, np.ndarray)}
        np.savez_compressed(path, robot_name=self.robot_name, coordinates=np.array(self.coordinates),
                            chain=np.array(self.chain), max_speed=self.max_speed, speed_limit=self.speed_limit,
                            wall_time=self.wall_time, **arrays)

    @classmethod
    def load(cls, path) -> "SimulationLog":
        """Read a log written by :meth:`save`."""
        with np.load(path) as data:
            values = {k: data[k] for k in data.files}
        return cls(robot_name=str(values.pop("robot_name")), coordinates=tuple(values.pop("coordinates").tolist()),
                   chain=tuple(values.pop("chain").tolist()), max_speed=float(values.pop("max_speed")),
                   speed_limit=float(values.pop("speed_limit")), wall_time=float(values.pop("wall_time")), **values)


def _scaled_robot(robot, scale: float):
    """The same robot with every mass (the kind's ``mass_parameters``) multiplied by ``scale`` (a
    controller's wrong belief)."""
    if scale == 1.0:
        return robot
    overrides = {k: robot.parameters[k] * scale for k in robot.kind.mass_parameters}
    return load(robot.name, **overrides)


def simulate(result, settings: SimulationSettings | None = None, progress=None) -> SimulationLog:
    """Track the planned motion of ``result`` in closed loop.

    Args:
        result: a :class:`planners.optimize.PlanResult` (its ``trajectory`` and ``robot``).
        settings: :class:`SimulationSettings`.
        progress: called as ``progress(simulated_time, total_time)`` about every simulated second.

    Returns:
        the :class:`SimulationLog`.

    Raises:
        fpr.sim.plant.PlantDivergedError: the plant's state became non-finite.
        ModelArgumentError: rates that are not integer multiples of each other, or an initial error on
            an unknown coordinate.
    """
    st = settings or SimulationSettings()
    robot = result.robot
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
    planned = inverse_dynamics(robot, motion)
    q_plan = planned.full_state(robot)[0]

    controller = CascadedController(_scaled_robot(robot, st.model_mass_scale), ctrl_settings)
    q0 = q_plan[0].copy()
    for name, offset in st.initial_error.items():
        if name not in robot.index:
            raise ModelArgumentError("initial_error", name,
                                     f"initial_error: unknown coordinate {name!r}; use one of {', '.join(robot.index)}")
        q0[robot.index[name]] += offset
    w0 = planned.rotor_speed[0] / np.sqrt(st.rotor_constant_scale)
    plant = Plant.from_minimal(robot, q0, np.zeros(robot.nq), w0)
    rng = np.random.default_rng(st.seed)
    noise_q, noise_v = st.measurement_noise
    wind = np.asarray(st.wind, dtype=float)
    wind = None if not wind.any() else wind
    speed_gain = np.sqrt(st.rotor_constant_scale)  # c_T w^2 scaled <=> w scaled by sqrt

    n, n_d, n_t = robot.nq, robot.n_drones, ticks.size
    log = {k: np.zeros(s) for k, s in {
        "q": (n_t, n), "v": (n_t, n), "roll_desired": (n_t, n_d), "speed_command": (n_t, n_d, 4),
        "speed": (n_t, n_d, 4), "thrust": (n_t, n_d), "torque": (n_t, n_d, 3), "saturated": (n_t, n_d, 4),
        "drone_height": (n_t, n_d), "closure_error": (n_t,)}.items()}
    start = time.perf_counter()
    next_report = 1.0
    for k, t in enumerate(ticks):
        q, v = plant.measure()
        log["q"][k], log["v"][k] = q, v
        log["speed"][k] = plant.rotor_speeds / speed_gain
        positions, log["closure_error"][k] = plant.drone_positions_and_closure_error()  # one kinematics pass
        log["drone_height"][k] = positions[:, 2]
        q_meas = q + noise_q * rng.normal(size=n) if noise_q else q
        v_meas = v + noise_v * rng.normal(size=n) if noise_v else v
        reference = Reference(motion[:5, k], planned.roll_rate[k], planned.roll_acceleration[k],
                              planned.thrust_vector[k])
        out = controller.update(t, q_meas, v_meas, reference)
        log["roll_desired"][k] = out.roll_desired
        log["speed_command"][k] = out.speeds
        log["thrust"][k], log["torque"][k] = out.allocation.thrust, out.allocation.torque
        log["saturated"][k] = out.allocation.saturated
        if k == n_t - 1:
            break
        command = np.clip(out.speeds, 0.0, robot.rotor_constants.max_speed) * speed_gain
        for _ in range(steps_per_tick):
            plant.step(command, dt, wind)
        if progress is not None and t + tick >= next_report:
            progress(t + tick, ticks[-1])
            next_report += 1.0
    speed_limit = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    return SimulationLog(robot.name, tuple(robot.layout.coordinates), tuple(robot.layout.chain), ticks,
                         log["q"], log["v"], motion[:3], planned.roll, log["roll_desired"], log["speed_command"],
                         log["speed"], log["thrust"], log["torque"], log["saturated"].astype(bool),
                         log["drone_height"], log["closure_error"], robot.rotor_constants.max_speed, speed_limit,
                         time.perf_counter() - start)
