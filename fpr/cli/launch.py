"""The first instructions of a command line: Ctrl-C and SIGTERM handled from the start, then the command.

The ``python -m`` modules (``fpr/plan.py``, ``fpr/campaign.py``, ``fpr/bench/__main__.py``,
``fpr/studies/__main__.py``) and the console scripts of ``pyproject.toml`` (``fpr-plan``...) call
:func:`launch` first. It imports nothing but the standard library, so that from its first instruction on:

* SIGTERM (a ``kill``, a job scheduler) raises ``KeyboardInterrupt`` as Ctrl-C (SIGINT) does;
* an interruption at any moment (while numpy, Pinocchio and the planner import, which takes seconds on a
  loaded machine, while a Dask cluster starts, during the work) ends the command with one line on stderr
  and exit code 130, never a traceback;
* the options are parsed by the command's light parser before the heavy modules are imported, so that
  ``--help`` and a mistyped option answer at once;
* after an interruption the process ends at once (:func:`finish`: ``os._exit``), without the exit handlers
  of the libraries (Dask's would close a half-started cluster and print its traceback).

A second Ctrl-C or SIGTERM while the command is already ending after an interruption ends the process at
once, exit 130.

Only the command-line layer calls this: importing fpr changes no signal handler.
"""

from __future__ import annotations

import importlib
import os
import sys

from fpr.cli.interrupts import (
    INTERRUPTED,
    INTERRUPTED_LINE,
    ending,
    handle_signals,
    interrupted,
    raise_if_interrupted,
)


def _target(path: str):
    """The object ``module:attribute``."""
    module, _, attribute = path.partition(":")
    return getattr(importlib.import_module(module), attribute)


def _say(line: str) -> None:
    try:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()
    except (OSError, ValueError):  # stderr closed: the exit code still tells
        pass


def launch(parser: str | None, work: str, argv=None) -> int:
    """Run a command with signals handled from the start; returns its exit code.

    Args:
        parser: ``module:function`` returning the command's argument parser, importable without the
            heavy modules (:mod:`fpr.cli.plan_options`); None: ``work`` is a whole ``main(argv)``.
        work: ``module:function``: with ``parser``, ``work(args, argv) -> 0 or 1`` run under
            :func:`fpr.cli.contract.run` once the options are parsed; without, ``main(argv) -> exit code``.
        argv: the options (default ``sys.argv[1:]``).
    """
    handle_signals()
    try:
        from fpr.tuning import tune_process

        tune_process()  # before numpy loads: one BLAS thread, freed memory kept in glibc's heap (fpr.tuning)
        from fpr.cli import contract

        if parser is None:
            try:
                main = _target(work)
            except Exception as error:  # noqa: BLE001 - a broken installation: one line, exit 3
                code, line = contract.ending_of(error)
                _say(line)
                return code
            code = main(argv)
        else:
            code = contract.command(_target(parser)(), argv, lambda args, given: _target(work)(args, given))
        raise_if_interrupted()
        return code
    except KeyboardInterrupt:
        ending()
        _say(INTERRUPTED_LINE)
        return INTERRUPTED
    except Exception:
        if not interrupted():
            raise
        # the interruption came out of C code as another error (numpy's import turns it into an ImportError)
        ending()
        _say(INTERRUPTED_LINE)
        return INTERRUPTED


def finish(code: int) -> None:
    """End the process with ``code``: at once (``os._exit``) after an interruption, else normally."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    if code == INTERRUPTED:
        os._exit(INTERRUPTED)
    raise SystemExit(code)
