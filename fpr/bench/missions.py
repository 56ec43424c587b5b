"""Long FPR missions made to measure: N way points on a closed curve in the square mission's workspace.

The planner's cost as a function of the mission's length (the scaling table,
``python -m fpr.bench --section scaling``) needs missions of any number of way points that are alike
travel by travel. :func:`loop_mission` makes them deterministically (no random numbers): the
end-effector goes round the circle of centre (0.5, 0.5) m and radius 0.5 m (inside the square
mission's 1 m x 1 m square, in the vertical plane), starting at its lowest point and stepping
:data:`LOOP_STEP` of arc per travel, lap after lap, for as many way points as asked. Every travel is
then the same chord, 2 r sin(step / 2) = 0.5 m, with the square's pace (3 s per metre: 1.5 s). The
link angle phi swings gently with the angle round the circle (phi = 5 pi/4 + 0.15 sin(theta), well
inside pi + m_ga <= phi <= 2 pi - m_ga) and q21 stays at pi/2 as on the square, so the planner has
orientation work to do too.
"""

from __future__ import annotations

import numpy as np

from planners.missions.mission import Mission

#: Centre [y, z] [m] and radius [m] of the circle the end-effector goes round.
LOOP_CENTRE = (0.5, 0.5)
LOOP_RADIUS = 0.5
#: Arc between two way points [rad] (pi / 3: six travels a lap, 0.5 m chords).
LOOP_STEP = np.pi / 3
#: Travel time per metre of chord [s/m]: the square mission's (1 m sides in 3 s).
SECONDS_PER_METRE = 3.0
#: phi's centre [rad] (the square's s0: both drones above the end-effector) and its swing [rad].
PHI_CENTRE = 5 * np.pi / 4
PHI_SWING = 0.15
#: q21 [rad], held as on the square.
Q21 = np.pi / 2


def loop_way_points(count: int) -> np.ndarray:
    """The ``count`` way points s = [y, z, phi, q21] of :func:`loop_mission` (count, 4) [m, m, rad, rad]."""
    theta = -np.pi / 2 + LOOP_STEP * np.arange(count)  # start at the circle's lowest point
    y = LOOP_CENTRE[0] + LOOP_RADIUS * np.cos(theta)
    z = LOOP_CENTRE[1] + LOOP_RADIUS * np.sin(theta)
    phi = PHI_CENTRE + PHI_SWING * np.sin(theta + np.pi / 2)  # theta + pi/2: phi starts at its centre
    return np.stack([y, z, phi, np.full(count, Q21)], axis=-1)


def loop_mission(count: int, via_points: int = 1, alpha: float = 0.5) -> Mission:
    """A mission of ``count`` way points round the circle (module docstring), ``via_points`` per travel.

    Args:
        count: number of way points, >= 2.
        via_points: n_vp of every travel, >= 0.
        alpha: the energy weight of the objective (3.26).

    Raises:
        MissionError: count < 2, a negative via_points or alpha outside [0, 1] (the mission's own checks).
    """
    points = loop_way_points(int(count)) if int(count) >= 1 else np.zeros((0, 4))
    chords = np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)
    return Mission(name=f"loop-{int(count)}", robot="fpr", way_points=points,
                   times=np.round(SECONDS_PER_METRE * chords, 12), via_points=via_points, alpha=alpha,
                   description=f"{int(count)} way points round a 0.5 m circle, {via_points} via points a "
                               "travel (fpr.bench.missions)",
                   source="fpr.bench.missions")
