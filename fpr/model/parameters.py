"""Parameters that a URDF cannot hold: rotor constants, limits, planning margins; and the physical ranges of
the parameters a user may override.

They are read from ``urdf/parameters.yaml``, the single file where the default numbers of the
robots live (the xacro sources read their geometric defaults from the same file). Geometry and
inertia are *not* taken from here by the model: :mod:`fpr.model.robot` reads them back from the URDF.

:data:`PARAMETER_RANGES` and :func:`check_parameters` bound the xacro arguments (``fpr.load(..., link_length=1.0)``,
a mission's ``[robot_parameters]``, ``--set``) to broad physical ranges for a multirotor and its chain: they
exclude the absurd (a subnormal mass, a 10 km link), not the unusual.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from fpr.model.description import URDF_DIR
from fpr.model.errors import ModelArgumentError

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


@dataclass(frozen=True)
class ParameterRange:
    """The physical range of a robot parameter.

    Attributes:
        low, high: least and largest value [unit].
        unit: the unit, as written in messages.
        meaning: what the range covers, in words (the message says it).
        zero: 0 is allowed too (the part is absent), besides [low, high].
    """

    low: float
    high: float
    unit: str
    meaning: str
    zero: bool = False

    def contains(self, value: float) -> bool:
        """``value`` is in the range (or 0, when allowed)."""
        return (self.zero and value == 0) or self.low <= value <= self.high

    def text(self) -> str:
        """The range as a message writes it: ``[0.01, 100] kg`` (``0 or [...]``)."""
        return f"{'0 or ' if self.zero else ''}[{self.low:g}, {self.high:g}] {self.unit}"


PARAMETER_RANGES: dict[str, ParameterRange] = {
    "link_length": ParameterRange(0.05, 10.0, "m", "a link of the chain, from a drone's own size to 10 m"),
    "link_mass": ParameterRange(1e-3, 100.0, "kg", "a link of the chain, from 1 g"),
    "link_radius": ParameterRange(5e-4, 0.5, "m", "a rod, from 1 mm thick"),
    "end_effector_mass": ParameterRange(1e-3, 100.0, "kg", "the end-effector's load, from 1 g (0: none)", zero=True),
    "end_effector_radius": ParameterRange(1e-3, 1.0, "m", "the end-effector's sphere, from 1 mm"),
    "drone_mass": ParameterRange(1e-2, 100.0, "kg", "a multirotor, from the smallest quadrotors that fly (about "
                                                    "10 g) to 100 kg"),
    "drone_ixx": ParameterRange(1e-6, 10.0, "kg m^2", "a multirotor's principal inertia, from that of a 10 g drone"),
    "drone_iyy": ParameterRange(1e-6, 10.0, "kg m^2", "a multirotor's principal inertia, from that of a 10 g drone"),
    "drone_izz": ParameterRange(1e-6, 10.0, "kg m^2", "a multirotor's principal inertia, from that of a 10 g drone"),
    "hinge_offset": ParameterRange(1e-3, 2.0, "m", "the joint below the drone's centre of mass, from 1 mm (0: at "
                                                   "it)", zero=True),
    "rotor_arm": ParameterRange(1e-2, 2.0, "m", "a rotor's distance to the drone's centre, from 1 cm"),
    "pivot_mass": ParameterRange(1e-9, 10.0, "kg", "the prototype's pivot rings (a model detail: tiny by design)"),
    "pivot_inertia": ParameterRange(1e-15, 1.0, "kg m^2", "the prototype's pivot rings (a model detail: tiny by "
                                                          "design)"),
    "leg_length": ParameterRange(0.05, 10.0, "m", "a leg of the spatial FPR, from a drone's own size to 10 m"),
    "leg_mass": ParameterRange(1e-3, 100.0, "kg", "a leg of the spatial FPR, from 1 g"),
    "leg_com": ParameterRange(1e-3, 10.0, "m", "a leg's centre of mass from its hinge, from 1 mm (0: at it)",
                              zero=True),
    "leg_radius": ParameterRange(5e-4, 0.5, "m", "a leg's tube, from 1 mm thick"),
    "leg_ixx": ParameterRange(1e-12, 100.0, "kg m^2", "a leg's principal inertia about its hinge"),
    "leg_iyy": ParameterRange(1e-12, 100.0, "kg m^2", "a leg's principal inertia about its hinge"),
    "leg_izz": ParameterRange(1e-12, 100.0, "kg m^2", "a leg's principal inertia about its hinge"),
    "platform_radius": ParameterRange(1e-3, 5.0, "m", "the spatial FPR's platform centre to a leg's hinge, from 1 mm"),
    "platform_mass": ParameterRange(1e-3, 100.0, "kg", "the spatial FPR's platform, from 1 g"),
    "platform_ixx": ParameterRange(1e-9, 100.0, "kg m^2", "the platform's principal inertia"),
    "platform_iyy": ParameterRange(1e-9, 100.0, "kg m^2", "the platform's principal inertia"),
    "platform_izz": ParameterRange(1e-9, 100.0, "kg m^2", "the platform's principal inertia"),
    "ball_offset": ParameterRange(1e-3, 2.0, "m", "the ball joint below the drone's centre of mass, from 1 mm (0: at "
                                                  "it)", zero=True),
    "ball_ring_mass": ParameterRange(1e-9, 10.0, "kg", "the spatial FPR's ball rings (a model detail: tiny by "
                                                       "design)"),
    "ball_ring_inertia": ParameterRange(1e-15, 1.0, "kg m^2", "the spatial FPR's ball rings (a model detail: tiny by "
                                                              "design)"),
}
"""Physical range of the xacro arguments of the built-in descriptions [SI units]; :func:`check_parameters` applies
it. The least values exclude subnormal and vanishing numbers (a body of 1e-300 kg), the largest a robot of
another scale; whether the rotors can lift the drones is checked against the rotor constants by the planner's
command line (:mod:`fpr.cli.checks`)."""


def check_parameters(overrides: dict, parameters: dict) -> None:
    """Check xacro overrides before a robot is built from them.

    Each key of :data:`PARAMETER_RANGES` given in ``overrides`` must be a finite number in its range; with
    every value (``parameters``: the parameter file's, overrides included), the principal inertias of the drones,
    of the spatial FPR's platform and of its legs (about their centres of mass) must satisfy the triangle
    inequalities (a physical, positive-definite inertia), and a leg's inertia about its hinge must exceed the
    part m c^2 of its mass at its centre. Whether the rotors can
    lift the robot is the planner's to say (a controller's model may well be too heavy to fly).

    Raises:
        ModelArgumentError: ``argument`` the offending key, ``value`` its value, the message what to give.
    """
    for key, value in overrides.items():
        bounds = PARAMETER_RANGES.get(key)
        if bounds is None:
            continue
        if not isinstance(value, numbers.Real) or isinstance(value, bool) or not math.isfinite(value):
            raise ModelArgumentError(key, value, f"{key} = {value!r}: give a finite number [{bounds.unit}]")
        if not bounds.contains(value):
            raise ModelArgumentError(key, value, f"{key} = {value:g} {bounds.unit} is outside the physical range "
                                                 f"{bounds.text()} ({bounds.meaning}): give a value in it")
    for body in ("drone", "platform"):
        names = tuple(f"{body}_i{a}{a}" for a in "xyz")
        inertia = [parameters.get(name) for name in names]
        if any(name in overrides for name in names) and all(isinstance(i, numbers.Real) for i in inertia):
            _check_triangle(names, inertia)
    _check_leg_inertia(overrides, parameters)


#: the spatial FPR's leg parameters that its inertia about the centre of mass depends on
_LEG_INERTIA = ("leg_mass", "leg_com", "leg_ixx", "leg_iyy", "leg_izz")


def _check_triangle(names, inertia, given=None, about: str = "") -> None:
    """Principal inertias ``inertia`` (of the parameters ``names``, whose values are ``given``: the same unless the
    inertias are derived from them) that no rigid body has: one larger than the sum of the two others.

    Raises:
        ModelArgumentError: naming the first such parameter.
    """
    given = inertia if given is None else given
    for i, name in enumerate(names):
        if inertia[i] > inertia[i - 1] + inertia[i - 2]:
            value = f"{name} = {given[i]:g} kg m^2" + (f" ({about} {inertia[i]:g} kg m^2)" if about else "")
            raise ModelArgumentError(name, given[i], f"{value} is more than the sum of the two other principal "
                                                     "inertias: no rigid body has that inertia; give smaller or "
                                                     "consistent values")


def _check_leg_inertia(overrides: dict, parameters: dict) -> None:
    """The spatial FPR's leg inertia, given about the hinge, moved to the centre of mass by the xacro
    (I_yy = leg_iyy - m c^2, likewise I_zz, m = leg_mass, c = leg_com): each must stay positive, which the xacro
    would otherwise refuse with its own exception.

    Raises:
        ModelArgumentError: naming the inertia given (or, when only the mass or the centre moved, that one).
    """
    if not any(key in overrides for key in _LEG_INERTIA):
        return
    values = {key: parameters.get(key) for key in _LEG_INERTIA}
    if not all(isinstance(v, numbers.Real) and math.isfinite(v) for v in values.values()):
        return
    transfer = values["leg_mass"] * values["leg_com"] ** 2
    for name in ("leg_iyy", "leg_izz"):
        if values[name] <= transfer:
            field = name if name in overrides else next(k for k in _LEG_INERTIA if k in overrides)
            given = "" if field == name else f"with {field} = {overrides[field]:g}, "
            raise ModelArgumentError(field, overrides[field],
                                     f"{given}{name} = {values[name]:g} kg m^2, the leg's inertia about its hinge, "
                                     f"must exceed leg_mass leg_com^2 = {transfer:g} kg m^2 (the part of a point "
                                     f"mass at the centre of mass): give a larger {name} or a smaller leg_mass or "
                                     "leg_com")
    names = ("leg_ixx", "leg_iyy", "leg_izz")  # about the centre of mass, as the URDF holds them
    _check_triangle(names, [values["leg_ixx"], values["leg_iyy"] - transfer, values["leg_izz"] - transfer],
                    [values[name] for name in names], "about the centre of mass")
