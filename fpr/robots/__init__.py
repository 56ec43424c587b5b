"""The robots: one module per robot, found by name in a registry.

Each robot is a :class:`~fpr.robots.base.RobotKind` subclass (its coordinates, kinematics, margins,
thrust from motion, closure, controller specifics, figure titles) in its own module; :func:`register`
adds it under its ``name`` and :func:`load` builds a :class:`~fpr.model.robot.Robot` of it::

    import fpr.robots
    robot = fpr.robots.load("prototype", link_length=1.0)   # also fpr.load(...)

    from my_lab.tripod import Tripod                         # a robot of your own:
    fpr.robots.register(Tripod)                              # one line, then load("tripod")

The built-in robots: ``"fpr"`` (:mod:`fpr.robots.fpr`), ``"prototype"`` (:mod:`fpr.robots.prototype`) and
``"fpr3"``, the spatial FPR (:mod:`fpr.robots.fpr3`).
An installed package can also declare its robots as entry points of the group ``fpr.robots``
(``tripod = "my_lab.tripod:Tripod"`` under ``[project.entry-points."fpr.robots"]`` of its pyproject):
they are registered on the first look-up, so that the command lines know them too.
"""

from __future__ import annotations

import importlib.metadata
import logging
from pathlib import Path

from fpr.model import description
from fpr.model.errors import RobotDefinitionError, UnknownRobotError
from fpr.model.parameters import PARAMETER_RANGES, check_parameters, load_parameters  # ranges: fpr.model.parameters
from fpr.model.robot import Robot
from fpr.robots.base import RobotKind
from fpr.robots.fpr import Fpr
from fpr.robots.fpr3 import Fpr3
from fpr.robots.prototype import Prototype

logger = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "fpr.robots"
"""The entry-point group in which installed packages declare robot kinds."""

_REGISTRY: dict[str, type[RobotKind]] = {}
_entry_points_loaded = False


def _load_entry_points() -> None:
    """Register the robot kinds that installed packages declare (once; a broken one is logged and skipped)."""
    global _entry_points_loaded
    if _entry_points_loaded:
        return
    _entry_points_loaded = True
    for entry in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        if entry.name in _REGISTRY:
            continue
        try:
            register(entry.load())
        except Exception as error:  # a third party's bug must not break the built-in robots
            logger.warning("robot %r of entry point %s not registered: %s", entry.name, entry.value, error)


def register(kind: type[RobotKind], replace: bool = False) -> type[RobotKind]:
    """Add a robot kind to the registry under ``kind.name``.

    Args:
        kind: a :class:`~fpr.robots.base.RobotKind` subclass.
        replace: allow replacing a kind registered under the same name.

    Returns:
        ``kind`` (so that ``register`` can decorate the class).

    Raises:
        RobotDefinitionError: ``kind`` is not a RobotKind subclass with a name, or the name is taken.
    """
    if not (isinstance(kind, type) and issubclass(kind, RobotKind)) or not isinstance(getattr(kind, "name", None), str):
        raise RobotDefinitionError(repr(kind), "register a subclass of fpr.robots.base.RobotKind with a `name`")
    if kind.name in _REGISTRY and _REGISTRY[kind.name] is not kind and not replace:
        raise RobotDefinitionError(kind.name, f"the name is taken by {_REGISTRY[kind.name].__qualname__}: choose "
                                              "another name, or register(..., replace=True)")
    _REGISTRY[kind.name] = kind
    return kind


def unregister(name: str) -> None:
    """Remove a robot kind from the registry (e.g. a test's).

    Raises:
        UnknownRobotError: no robot of that name.
    """
    get(name)
    del _REGISTRY[name]


def get(name: str) -> type[RobotKind]:
    """The robot kind registered under ``name``.

    Raises:
        UnknownRobotError: no robot of that name (the message lists the registered ones).
    """
    for attempt in range(2):
        try:
            return _REGISTRY[name]
        except (KeyError, TypeError):
            if attempt:
                raise UnknownRobotError(str(name), names()) from None
            _load_entry_points()


def names() -> tuple[str, ...]:
    """The registered robot names, in registration order (the built-in ones first, then the entry points')."""
    _load_entry_points()
    return tuple(_REGISTRY)


def constraint_kinds() -> dict[str, tuple[str, str]]:
    """The constraint kinds of the registered robots (``RobotKind.constraint_kinds``): name prefix ->
    (unit, what it bounds), the first robot's text where two robots name the same kind.

    Raises:
        RobotDefinitionError: two robots give the same kind different units.
    """
    kinds = tuple(get(name) for name in names())
    cached = _constraint_kinds_cache.get(kinds)
    if cached is None:
        cached = {}
        for kind in kinds:
            for key, (unit, text) in kind.constraint_kinds.items():
                if key in cached and cached[key][0] != unit:
                    raise RobotDefinitionError(kind.name, f"its constraint kind {key!r} is in {unit}, another "
                                                          f"robot's in {cached[key][0]}: rename it")
                cached.setdefault(key, (unit, text))
        _constraint_kinds_cache.clear()
        _constraint_kinds_cache[kinds] = cached
    return cached


def attitude_kinds() -> frozenset[str]:
    """The constraint kinds that bound the drones' attitude, of every registered robot (``attitude_kinds``)."""
    return frozenset(k for name in names() for k in get(name).attitude_kinds)


_constraint_kinds_cache: dict[tuple, dict] = {}


def load(name: str = "fpr", urdf: str | Path | None = None, **xacro_args) -> Robot:
    """Load a robot into Pinocchio.

    Args:
        name: a registered robot: "fpr" (two drones and the end-effector), "prototype" (one drone,
            chain pinned), "fpr3" (three drones carrying a platform in 6 DOF), or one you registered.
        urdf: a URDF file to use instead of the kind's (``kind.urdf``, e.g. the committed ``urdf/fpr.urdf``).
        **xacro_args: overrides of the description's xacro arguments (the geometric and inertial
            keys of ``urdf/parameters.yaml`` and ``rotor_arm``, e.g. ``link_length=1.0``, and the
            arguments of the kind's own xacro files): the URDF is then regenerated from the kind's xacro
            file with them, and ``robot.parameters`` shows them too. A kind without a committed URDF
            (``kind.urdf`` None) is always generated from its xacro file.

    Returns:
        the :class:`~fpr.model.robot.Robot`, its kind bound as ``robot.kind``.

    Raises:
        UnknownRobotError: a name that is not registered.
        RobotDefinitionError: a key that is not a xacro argument (rotor constants, margins: edit the
            parameter file instead), both ``urdf`` and overrides given, or a URDF the kind cannot use.
        ModelArgumentError: an override out of its physical range (:func:`check_parameters`).
    """
    kind = get(name)
    if urdf is not None and xacro_args:
        raise RobotDefinitionError(name, "give either a URDF file or xacro arguments, not both")
    params = {**load_parameters(), **xacro_args}
    check_parameters(xacro_args, params)
    if urdf is not None:
        text = Path(urdf).read_text(encoding="utf-8")
    elif xacro_args or kind.urdf is None:
        text = description.generate_urdf(kind.xacro, **xacro_args)
    else:
        text = Path(kind.urdf).read_text(encoding="utf-8")
    return Robot(kind, text, params)


register(Fpr)
register(Prototype)
register(Fpr3)

BUILTIN: tuple[str, ...] = tuple(_REGISTRY)
"""The names of the robots that come with the library: ("fpr", "prototype", "fpr3")."""

__all__ = [
    "BUILTIN",
    "ENTRY_POINT_GROUP",
    "PARAMETER_RANGES",
    "RobotKind",
    "check_parameters",
    "get",
    "load",
    "names",
    "register",
    "unregister",
]
