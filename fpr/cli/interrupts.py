"""Ctrl-C and SIGTERM in the command lines: both raise ``KeyboardInterrupt``; after the first, a second one
ends the process at once. Standard library only: :mod:`fpr.cli.launch` installs these before any heavy
import, :mod:`fpr.cli.contract` maps the interruption to exit code 130 and one line.
"""

from __future__ import annotations

import os
import signal
import sys

INTERRUPTED = 130
"""The exit code of an interrupted command."""
INTERRUPTED_LINE = ("interrupted (Ctrl-C or SIGTERM): nothing written; a previous --out folder is left as it "
                    "was")
"""The line an interrupted command prints on stderr (a command may say more, e.g. what a campaign kept)."""


_received = False


def on_signal(signum, frame):
    """The handler of SIGINT and SIGTERM: records the interruption, raises ``KeyboardInterrupt``."""
    global _received
    _received = True
    raise KeyboardInterrupt


def interrupted() -> bool:
    """Whether a signal came that no handler has dealt with yet (:func:`ending` deals with it)."""
    return _received


def raise_if_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` again if a signal came whose ``KeyboardInterrupt`` was swallowed.

    Python ignores (prints and drops) an exception raised in a weakref callback or a destructor: a signal that
    lands while the import system runs one of its module-lock callbacks, as modules load, would otherwise let
    the command run on. The command lines call this where they report progress, before they write their output
    and when their work returns.
    """
    if _received:
        raise KeyboardInterrupt


def _end_now(signum, frame):
    os._exit(INTERRUPTED)


def _unraisable(info) -> None:
    """Python's hook for an exception it cannot raise: quiet for the interruption (raised again by
    :func:`raise_if_interrupted`), Python's own report for anything else.
    """
    if info.exc_type is not None and issubclass(info.exc_type, KeyboardInterrupt):
        return
    sys.__unraisablehook__(info)


def handle_signals() -> None:
    """SIGINT and SIGTERM raise ``KeyboardInterrupt`` (main thread; elsewhere nothing changes); an interruption
    Python drops in a callback is not reported as a traceback (:func:`raise_if_interrupted` raises it again).
    """
    try:
        signal.signal(signal.SIGINT, on_signal)
        signal.signal(signal.SIGTERM, on_signal)
    except ValueError:  # not the main thread of the main interpreter
        return
    sys.unraisablehook = _unraisable


def ending() -> None:
    """An interruption is being handled: a second SIGINT or SIGTERM ends the process at once (exit 130), and
    :func:`raise_if_interrupted` no longer raises for the first.
    """
    global _received
    _received = False
    try:
        signal.signal(signal.SIGINT, _end_now)
        signal.signal(signal.SIGTERM, _end_now)
    except ValueError:
        pass
