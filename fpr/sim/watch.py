"""The closed loop's watch for a lost robot: what makes a simulation stop before its end.

At every inner-loop tick :func:`fpr.sim.closed_loop.simulate` asks :meth:`Watch.check` whether the
robot is lost, in this order (the first that fires is reported):

1. a state that is not finite (the plant's q, v or the measured state);
2. a drone below the ground: its hinge or its centre of mass lower than ``robot.kind.ground_height``
   minus ``ground_tolerance``;
3. the chain's closure broken: the plant's loop-closure error past ``max_closure_error``;
4. a state that diverges: a drone's hinge faster than ``max_drone_speed``, a drone spinning faster than
   ``max_drone_rate``, or a drone's thrust axis tilted past ``max_tilt`` from the vertical (upside down);
5. the tracking error of a planning coordinate (measured minus planned) past ``max_tracking_error``.

The bounds are :class:`fpr.sim.closed_loop.SimulationSettings` fields; their defaults are far from
what the reference missions reach (square: tracking errors < 1 cm, closure error < 1e-6 m, drones
> 0.5 m above the ground). A failure is one line: what happened, to which drone or coordinate, the
value and the bound, and when, e.g. "drone 2 hinge below the ground (z = -0.8061 m < -0.8 m:
ground -0.75 m, tolerance 0.05 m) at t = 0.522 s".
"""

from __future__ import annotations

import numpy as np


def _past(value: float, bound: float) -> str:
    """``value`` with enough significant digits (4 at least) to read as past ``bound`` (0.2001, not 0.2)."""
    for digits in range(4, 17):
        text = f"{value:.{digits}g}"
        if float(text) != bound:
            return text
    return repr(value)


class Watch:
    """The bounds of one simulation, and the check of a state against them.

    Args:
        robot: the simulated :class:`~fpr.model.robot.Robot`.
        settings: the :class:`fpr.sim.closed_loop.SimulationSettings` holding the bounds.
    """

    def __init__(self, robot, settings):
        self.ground = float(robot.kind.ground_height)
        self.ground_tolerance = float(settings.ground_tolerance)
        self.max_closure_error = float(settings.max_closure_error)
        self.max_drone_speed = float(settings.max_drone_speed)
        self.max_drone_rate = float(settings.max_drone_rate)
        self.max_tilt = float(settings.max_tilt)
        self.max_tracking_error = float(settings.max_tracking_error)
        self.chain = tuple(robot.layout.chain)
        self.units = tuple(robot.kind.chain_units)
        self.chain_index = robot.indices(robot.layout.chain)

    def check(self, t: float, plant, q, v, positions, closure_error: float, planned) -> str | None:
        """The failure at time t, or None when the robot is not lost.

        Args:
            t: simulated time [s].
            plant: the :class:`~fpr.sim.plant.Plant` (its hinges, tilts and speeds are read).
            q: the measured configuration in thesis coordinates, shape (n,) [m, rad].
            v: the measured velocity, shape (n,) [m/s, rad/s].
            positions: the drones' centres of mass, shape (n_d, 3) [m].
            closure_error: the plant's loop-closure error [m].
            planned: the planned planning coordinates at t, shape (n_s,) [m, rad].

        Returns:
            one line naming what happened, the value, the bound and the time; None.
        """
        at = f"at t = {t:.3f} s"
        if not (np.isfinite(plant.qc).all() and np.isfinite(plant.vc).all() and np.isfinite(q).all()
                and np.isfinite(v).all()):
            return f"the state diverged (non-finite numbers in the plant state) {at}"
        floor = self.ground - self.ground_tolerance
        for label, heights in (("hinge", plant.drone_joint_positions()[:, 2]),
                               ("centre of mass", np.asarray(positions)[:, 2])):
            i = int(np.argmin(heights))
            if heights[i] < floor:
                z = _past(heights[i], floor)
                return (f"drone {i + 1} {label} below the ground (z = {z} m < {floor:.4g} m: "
                        f"ground {self.ground:g} m, tolerance {self.ground_tolerance:g} m) {at}")
        if not closure_error <= self.max_closure_error:
            value = _past(closure_error, self.max_closure_error)
            return f"the chain's closure broke (closure error {value} m > {self.max_closure_error:g} m) {at}"
        linear, angular = plant.drone_speeds()
        tilts = plant.drone_tilts()
        for values, bound, what, unit in ((linear, self.max_drone_speed, "speed", "m/s"),
                                          (angular, self.max_drone_rate, "angular speed", "rad/s"),
                                          (tilts, self.max_tilt, "tilt from the vertical", "rad")):
            i = int(np.argmax(values))
            if values[i] > bound:
                value = _past(values[i], bound)
                return f"drone {i + 1} diverged ({what} {value} {unit} > {bound:g} {unit}) {at}"
        error = np.abs(np.asarray(q)[self.chain_index] - planned)
        bound = self.max_tracking_error
        j = int(np.argmax(error))
        if error[j] > bound:
            value, unit = _past(error[j], bound), self.units[j]
            return f"tracking lost on {self.chain[j]} (error {value} {unit} > {bound:g} {unit}) {at}"
        return None


__all__ = ["Watch"]
