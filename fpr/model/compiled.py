"""The optional compiled parts of the closed loop's tick and of the planner (``setup.py``'s C extensions) and the
switch that chooses between each and its Python reference.

Every compiled part has a switch (``Allocator(compiled=...)``, ``CascadedController.compiled_inner``,
``Robot.compiled_attitude``, ``Watch.compiled_screen``, ``Plant.compiled_step``,
``ClosedChainModel.compiled_velocity``, ``fpr.model.jets.compiled``) read the same way by :func:`choose`: None
(the default) uses the compiled part when it was built and fits the robot, else the Python reference; False
always uses the Python reference; True requires the compiled part (a RuntimeError that says how to build it
otherwise).
"""

from __future__ import annotations

import importlib

from fpr.model.errors import ModelArgumentError

#: how to get the extensions: said by every error that wants one
BUILD_HINT = ("build it with `pip install -e .` (a C compiler is needed) or "
              "`python setup.py build_ext --inplace`")


def load_extension(name: str):
    """The extension module ``name`` (e.g. ``"controllers._alloc"``), or None when it was not built (no
    compiler at install time) or cannot be imported."""
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


def choose(switch: bool | None, function, name: str, setting: str, part: str, fits: bool = True):
    """The compiled ``function`` to call under ``switch``, or None for the Python reference.

    Args:
        switch: None, False or True (module docstring).
        function: the extension's function, or None when it is not built.
        name: the switch's name, for the error on a value that is not one (e.g. ``"compiled_attitude"``).
        setting: the switch as the user sets it, for the error (e.g. ``"Robot.compiled_attitude = True"``).
        part: what is compiled and where, for the error (e.g. ``"attitude model (fpr/model/_attitude.c)"``).
        fits: whether the robot is within the compiled part's fixed sizes.

    Raises:
        ModelArgumentError: ``switch`` is not None, False or True.
        RuntimeError: ``switch`` is True and the part is not built or does not fit.
    """
    if switch is not None and not isinstance(switch, bool):
        raise ModelArgumentError(name, switch, f"{name} = {switch!r}: give None (the compiled part when it is "
                                               "built), False (the Python reference) or True (require it)")
    if switch is False:
        return None
    if function is not None and fits:
        return function
    if switch:
        raise RuntimeError(f"{setting}: the compiled {part} is not built or does not fit this robot; {BUILD_HINT}")
    return None


__all__ = ["BUILD_HINT", "choose", "load_extension"]
