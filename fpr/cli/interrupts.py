"""Ctrl-C and SIGTERM in the command lines: both raise ``KeyboardInterrupt``; after the first, a second one
ends the process at once. Standard library only: :mod:`fpr.cli.launch` installs these before any heavy
import, :mod:`fpr.cli.contract` maps the interruption to exit code 130 and one line.
"""

from __future__ import annotations

import os
import signal

INTERRUPTED = 130
"""The exit code of an interrupted command."""
INTERRUPTED_LINE = ("interrupted (Ctrl-C or SIGTERM): nothing written; a previous --out folder is left as it "
                    "was")
"""The line an interrupted command prints on stderr (a command may say more, e.g. what a campaign kept)."""


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def _end_now(signum, frame):
    os._exit(INTERRUPTED)


def handle_signals() -> None:
    """SIGINT and SIGTERM raise ``KeyboardInterrupt`` (main thread; elsewhere nothing changes)."""
    try:
        signal.signal(signal.SIGINT, _interrupt)
        signal.signal(signal.SIGTERM, _interrupt)
    except ValueError:  # not the main thread of the main interpreter
        pass


def ending() -> None:
    """An interruption is being handled: a second SIGINT or SIGTERM ends the process at once (exit 130)."""
    try:
        signal.signal(signal.SIGINT, _end_now)
        signal.signal(signal.SIGTERM, _end_now)
    except ValueError:
        pass
