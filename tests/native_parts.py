"""The native parts (fpr._native) in the tests.

A test of a native part runs it, and fails when the part is not built: a native install builds every part or
fails (setup.py), so a missing part is a broken install, never a reason to skip. The pure-Python install
(``FPR_NATIVE=0 pip install -e .``) runs its tests with ``FPR_NATIVE=0`` too: those tests then skip, saying
why.
"""

from __future__ import annotations

import os

import pytest

from fpr import _native as native

#: the run of a pure-Python install: every native part off
PURE = os.environ.get("FPR_NATIVE", "").strip().lower() in ("0", "off")

#: a test that runs a native part
needs_native = pytest.mark.skipif(PURE, reason="FPR_NATIVE=0: the pure-Python install's run, no native part "
                                               "(a native install runs this test)")


def native_module(part: str):
    """The extension module of ``part`` (its first: ``native.PARTS``); a test failure when it is not built."""
    name = native.PARTS[part][0]
    module = native.module(name)
    assert module is not None, (f"the native part {part!r} (fpr._native.{name}) is not built: {native.BUILD_HINT}; "
                                "a pure-Python install runs the tests with FPR_NATIVE=0")
    return module


__all__ = ["PURE", "native_module", "needs_native"]
