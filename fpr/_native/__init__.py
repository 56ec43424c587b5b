"""fpr's native parts, all built from this folder (``setup.py``), and the one switch between each and its
Python reference.

The parts (each the same computation as its Python path, equal to round-off; ``tests/test_*_compiled.py``):

* ``plant``: the plant's RKMK4 steps and its kinematic points (``fpr/sim/plant.py``) by Pinocchio's C++
  ``constraintDynamics``, ``integrate`` and ``dIntegrate`` (``cpp/plant.cpp``);
* ``measure``: the measurement (``ClosedChainModel.to_minimal``): Pinocchio's forward kinematics of the closed
  chain, the robot kind's reads of its placements, the unwrapping and the velocity's least squares on Pinocchio's
  joint Jacobians (``cpp/measure.cpp``, ``cpp/minimal.cpp``);
* ``attitude``: the attitude model (``Robot.attitude_model``): M_p, the nonlinear effects and the drones'
  frame Jacobians by Pinocchio's ``crba``, ``nonLinearEffects`` and ``getFrameJacobian``
  (``cpp/minimal.cpp``), the rest in C (``attitude.c``);
* ``allocation`` and ``inner``: the allocation tick and the inner loop's float part (``alloc.c``);
* ``watch``: the watch's screen (``watch.c``);
* ``jets``: the planner's jet products and small batched solves (``jets.c``);
* ``loop``: the closed loop's plain ticks between two outer-loop updates in one native call (``cpp/loop.cpp``,
  :mod:`fpr.sim.native_loop`), each tick by the kernels of the parts above (it runs when they are on too); the
  ticks it does not do (an outer-loop update, a watch that fires, events, noise...) it hands back to Python.

The switch: the environment variable ``FPR_NATIVE``, read at import, or :func:`configure` (and
:func:`switched` for a block of code):

* unset, ``1`` or ``on``: every part that is built (a part not built runs its Python path, with one warning);
* ``0`` or ``off``: no native part (every Python path; in the environment, no native code is even loaded);
  ``FPR_NATIVE=0 pip install -e .`` is also the pure-Python install, which builds none;
* ``require``: every part, an error when one is not built;
* a comma-separated list of parts, e.g. ``plant,measure``: those parts only.

A part whose extension is there but cannot be loaded (e.g. built against another Pinocchio than the one
installed) is an error, whatever the switch, except ``0``: rebuild with ``pip install -e .``.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import logging
import os

logger = logging.getLogger(__name__)

#: each part and the extension modules it calls (fpr._native.<name>)
PARTS = {"plant": ("_pinocchio",), "measure": ("_pinocchio",), "attitude": ("_attitude", "_pinocchio"),
         "allocation": ("_alloc",), "inner": ("_alloc",), "watch": ("_watch",), "jets": ("_jets",),
         "loop": ("_pinocchio", "_alloc", "_attitude", "_watch")}
#: how to get the native parts, said by every error that wants one
BUILD_HINT = "build them with `pip install -e .` (a C++ compiler is needed)"

_modules: dict[str, object] = {}  # extension name -> module, or None when not built
_on: dict[str, bool] = {}  # part -> on
_required = False
_active: dict[str, object] = {}  # part -> its first module when on and built, else None (what use() returns)
_warned: set[str] = set()
#: FPR_NATIVE=0 (or off) in the environment: no native code is ever loaded in this process
_NEVER = os.environ.get("FPR_NATIVE", "").strip().lower() in ("0", "off")


class NativeError(RuntimeError):
    """A native part that must run cannot: not built (with ``FPR_NATIVE=require``), or built but not
    loadable.
    """


def _load(name: str):
    """The extension module ``fpr._native.<name>``, or None when it was not built (no file).

    Raises:
        NativeError: the file is there but cannot be loaded.
    """
    if name in _modules:
        return _modules[name]
    if _NEVER:  # FPR_NATIVE=0 in the environment: this process loads no native code
        return None
    full = f"{__name__}.{name}"
    module = None
    if importlib.util.find_spec(full) is not None:
        try:
            if name == "_pinocchio":
                import pinocchio  # its libraries loaded first: the extension finds them by their SONAME

                module = importlib.import_module(full)
                if module.PINOCCHIO_VERSION != pinocchio.__version__:
                    raise ImportError(f"built against Pinocchio {module.PINOCCHIO_VERSION}, but Pinocchio "
                                      f"{pinocchio.__version__} is installed")
            else:
                module = importlib.import_module(full)
        except ImportError as error:
            raise NativeError(f"the native part {full} cannot be loaded ({error}); rebuild it: "
                              f"`pip install -e .`, or run the Python paths: FPR_NATIVE=0") from error
    _modules[name] = module
    return module


def _resolve() -> None:
    """Recompute what :func:`use` returns."""
    _active.clear()
    for part, names in PARTS.items():
        module = None
        if _on[part]:
            modules = [_load(name) for name in names]
            if all(m is not None for m in modules):
                module = modules[0]
            elif _required:
                missing = ", ".join(f"fpr._native.{n}" for n, m in zip(names, modules, strict=True) if m is None)
                raise NativeError(f"FPR_NATIVE=require: the native part {part!r} is not built ({missing}); "
                                  f"{BUILD_HINT}")
            elif part not in _warned:
                _warned.add(part)
                logger.warning("the native part %r is not built: its Python path runs (a pure-Python "
                               "install? FPR_NATIVE=0 says so and silences this; %s)", part, BUILD_HINT)
        _active[part] = module


def _parse(value) -> tuple[dict[str, bool], bool]:
    """The parts on and the require flag of a setting (module docstring)."""
    if value is None or value is True or (isinstance(value, str) and value.strip().lower() in ("", "1", "on")):
        return dict.fromkeys(PARTS, True), False
    if value is False or (isinstance(value, str) and value.strip().lower() in ("0", "off")):
        return dict.fromkeys(PARTS, False), False
    if isinstance(value, str) and value.strip().lower() == "require":
        return dict.fromkeys(PARTS, True), True
    names = [n.strip() for n in value.split(",") if n.strip()] if isinstance(value, str) else list(value)
    unknown = [n for n in names if n not in PARTS]
    if unknown:
        raise ValueError(f"FPR_NATIVE = {value!r}: unknown part(s) {', '.join(map(repr, unknown))}; give 1, 0, "
                         f"require or a comma-separated list of {', '.join(PARTS)}")
    return {part: part in names for part in PARTS}, False


def configure(value=True) -> None:
    """Set the switch (what ``FPR_NATIVE`` sets at import; the module docstring says what each value means).

    Args:
        value: True, ``"1"`` or ``"on"`` (every built part), False, ``"0"`` or ``"off"`` (none), ``"require"``
            (every part, an error when one is not built), or an iterable or comma-separated string of the parts
            to run natively (the others run their Python paths).

    Raises:
        ValueError: an unknown part or value.
        NativeError: ``"require"`` and a part is not built, or a part is built but cannot be loaded.
    """
    global _required
    on, required = _parse(value)
    before = dict(_on), _required
    _on.clear()
    _on.update(on)
    _required = required
    try:
        _resolve()
    except NativeError:  # the switch as it was
        _on.clear()
        _on.update(before[0])
        _required = before[1]
        _resolve()
        raise


def _parse_environment():
    """The setting of the environment variable FPR_NATIVE (None when unset)."""
    return os.environ.get("FPR_NATIVE")


def use(part: str):
    """The extension module of ``part`` when it runs native, else None (its Python path runs)."""
    return _active[part]


def module(name: str):
    """The extension module ``fpr._native.<name>`` (e.g. ``"_pinocchio"``), or None when it is not built."""
    return _load(name)


def parts() -> dict[str, bool]:
    """Each part and whether it runs native now."""
    return {part: _active[part] is not None for part in PARTS}


def built() -> dict[str, bool]:
    """Each part and whether its extension modules are built (whatever the switch)."""
    return {part: all(_load(name) is not None for name in names) for part, names in PARTS.items()}


@contextlib.contextmanager
def switched(**on: bool):
    """A block of code with some parts switched on or off; the switch as it was afterwards.

    Example: ``with fpr._native.switched(plant=False): ...`` runs the plant's Python steps in the block.
    """
    unknown = [p for p in on if p not in PARTS]
    if unknown:
        raise ValueError(f"unknown part(s) {', '.join(map(repr, unknown))}; give some of {', '.join(PARTS)}")
    before, required = dict(_on), _required
    _on.update({p: bool(v) for p, v in on.items()})
    try:
        _resolve()
        yield parts()
    finally:
        _on.clear()
        _on.update(before)
        globals()["_required"] = required
        _resolve()


configure(_parse_environment())

__all__ = ["BUILD_HINT", "PARTS", "NativeError", "built", "configure", "module", "parts", "switched", "use"]
