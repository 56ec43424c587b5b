"""Parameters that a URDF cannot hold: rotor constants, limits, planning margins.

They are read from ``urdf/parameters.yaml``, the single file where the default numbers of the
robots live (the xacro sources read their geometric defaults from the same file). Geometry and
inertia are *not* taken from here by the model: :mod:`fpr.model.robot` reads them back from the URDF.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from fpr.model.description import URDF_DIR

PARAMETERS_FILE = Path(URDF_DIR) / "parameters.yaml"


def load_parameters(path: str | Path | None = None) -> dict:
    """Return the raw parameter dictionary of ``urdf/parameters.yaml`` (or of ``path``)."""
    with open(path or PARAMETERS_FILE, encoding="utf-8") as stream:
        return yaml.safe_load(stream)


@dataclass(frozen=True)
class RotorConstants:
    """Constants of the four rotors of a quadrotor (seed eq. 3.2-3.3, 3.48).

    Attributes:
        thrust_coefficient: c_T, rotor thrust f = c_T w^2 [N/(rad/s)^2].
        drag_coefficient: c_Q, rotor drag torque c_Q w^2 [N m/(rad/s)^2].
        max_speed: w_max, largest rotor speed [rad/s].
        spin: sense of rotation of each rotor about body +z (+1 or -1); the drag torque on the body
            is ``-spin * c_Q * w^2`` about body z.
        time_constant: first-order motor lag, for simulation [s].
    """

    thrust_coefficient: float
    drag_coefficient: float
    max_speed: float
    spin: np.ndarray = field(repr=False)
    time_constant: float = 0.02

    @property
    def max_rotor_thrust(self) -> float:
        """Thrust of one rotor at full speed, c_T w_max^2 [N]."""
        return self.thrust_coefficient * self.max_speed**2


@dataclass(frozen=True)
class Margins:
    """Planning margins (seed 3.27-3.48).

    Attributes:
        ground: m_gd, least height of a drone joint above the ground z = -L [m].
        angle: m_ga, least angular distance to a singularity, and to a rolled-over drone [rad].
        force: m_gf, rotor force margin [N].
        rotor_speed: m_gr, rotor speed margin below w_max [rad/s].
    """

    ground: float
    angle: float
    force: float
    rotor_speed: float


def rotor_constants(params: dict | None = None) -> RotorConstants:
    """Rotor constants from the parameter file."""
    p = params or load_parameters()
    return RotorConstants(
        thrust_coefficient=float(p["rotor_thrust_coefficient"]),
        drag_coefficient=float(p["rotor_drag_coefficient"]),
        max_speed=float(p["rotor_max_speed"]),
        spin=np.asarray(p["rotor_spin"], dtype=float),
        time_constant=float(p["rotor_time_constant"]),
    )


def margins(params: dict | None = None) -> Margins:
    """Planning margins from the parameter file."""
    p = params or load_parameters()
    return Margins(
        ground=float(p["margin_ground"]),
        angle=float(p["margin_angle"]),
        force=float(p["margin_force"]),
        rotor_speed=float(p["margin_rotor_speed"]),
    )
