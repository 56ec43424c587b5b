"""The contract of a command line: exit codes, one-line messages, tracebacks only under ``--debug``.

:func:`run` calls a command's work and turns what it raises into the documented exit code and one line
on stderr (:data:`EXIT_CODES` is the text ``--help`` shows):

* :class:`fpr.model.errors.FprError` (raised on purpose, its message says what to do), ``OSError``
  (a file that cannot be read or written) and ``MemoryError``: bad input, exit 2;
* ``KeyboardInterrupt`` (Ctrl-C, or SIGTERM, turned into one while the work runs): one line, exit 130;
* anything else is a bug: one line saying so, the exception's type and message and where to report
  it, exit 3; the traceback only with ``--debug``.

The work returns 0 (success) or 1 (the result breaks a limit) itself. Every line is at most
:data:`MAX_LINE` characters (a message that quotes a long input is cut, saying how much was left out).
The signals are handled from the command's first instruction by :mod:`fpr.cli.launch`.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import errno
import logging
import re
import signal
import sys
import threading
import traceback
import warnings

import fpr
from fpr.cli import interrupts
from fpr.model.errors import FprError

OK, LIMIT_BROKEN, BAD_INPUT, INTERNAL_ERROR, INTERRUPTED = 0, 1, 2, 3, 130

EXIT_CODES = """exit codes:
  0    success: every constraint holds (and, with --simulate, the robot was not lost)
  1    the result breaks a limit: the plan violates a constraint, or the simulation lost the robot or broke
       a physical limit (ground, singularity, rotor speeds, fixed point; eating into a design margin is only
       reported) (the output folder is still written; the message names the constraint, or what happened and when)
  2    bad input: an option, the mission file, a robot parameter, a size of work over the limits, or an
       --out folder that cannot be written (nothing is written; a previous --out folder is left as it was)
  3    internal error: a bug in fpr (one line says so; --debug shows the traceback)
  130  interrupted (Ctrl-C, SIGTERM): nothing is written, a previous --out folder is left as it was"""

REPORT = "please report it, with the command line and the output of --debug, to the fpr maintainers " \
         "(the issue tracker of the fpr repository)"


MAX_LINE = 600
"""Longest line a command prints for an error [characters]; longer messages are cut in the middle."""


def one_line(text, limit: int = MAX_LINE) -> str:
    """``text`` on one line (the lines of a multi-line message joined by ``; ``), cut to ``limit`` characters.

    A longer text keeps its beginning and its end (where the messages say what to do) and says how many
    characters were left out.
    """
    line = "; ".join(part.strip() for part in str(text).splitlines() if part.strip())
    if len(line) <= limit:
        return line
    keep = (limit - 40) // 2
    return f"{line[:keep]} ...({len(line) - 2 * keep} characters left out)... {line[-keep:]}"


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``error: ... (see --help)``) and exit 2.

    A value that starts with a minus sign and a digit, a point, ``inf`` or ``nan`` (``--times -1,1``,
    ``--wind -2,0,0``) is taken as the option's value, not as an unknown option, so that it reaches the
    command's own checks and their message.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)

    def error(self, message):
        """Exit with code 2 and ``message`` on one line of stderr, pointing at ``--help``."""
        self.exit(BAD_INPUT, f"error: {one_line(message)} (see {self.prog} --help)\n")


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults shown in the help (unless None, a flag's False, an empty list, or the help already speaks
    of its default), the description and the epilog (exit codes) as written.
    """

    def _expand_help(self, action):
        if isinstance(action.choices, LazyChoices):  # the help does not list them: no registry to import
            action = copy.copy(action)
            action.choices = None
        return super()._expand_help(action)

    def _get_help_string(self, action):
        default = action.default
        if default is None or default is False or default == [] or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


class LazyChoices:
    """The choices of an option read from a registry only when needed (a value to check, an error to
    write), so that building the parser and ``--help`` import nothing heavy; give the option a ``metavar``.

    Args:
        names: a function returning the names (e.g. the keys of :data:`planners.methods.METHODS`).
    """

    def __init__(self, names):
        self._names = names

    def __contains__(self, value) -> bool:
        return value in tuple(self._names())

    def __iter__(self):
        return iter(tuple(self._names()))

    def __len__(self) -> int:
        return len(tuple(self._names()))


def add_debug(parser: argparse.ArgumentParser) -> None:
    """Add ``--debug``: show the traceback of an internal error or an interruption."""
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an internal error (exit 3) or of Ctrl-C")


@contextlib.contextmanager
def _terminate_as_interrupt():
    """SIGTERM (a ``kill``, a job scheduler) raises KeyboardInterrupt, so that the work cleans up (main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    previous = signal.signal(signal.SIGTERM, interrupts.on_signal)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def command(parser: argparse.ArgumentParser, argv, work) -> int:
    """A command line's ``main``: parse ``argv`` (default ``sys.argv[1:]``), then :func:`run` ``work(args, argv)``.

    ``--help`` returns 0 and an option argparse refuses returns 2 (its one line already printed); the parser
    must have ``--debug`` (:func:`add_debug`).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # --help (0), or an option argparse refuses (2, one line printed)
        return stop.code if isinstance(stop.code, int) else BAD_INPUT
    except (KeyboardInterrupt, Exception) as error:  # noqa: BLE001 - e.g. a registry that fails to import
        code, line = _ended(error)
        print(line, file=sys.stderr)
        return code
    return run(lambda: work(args, argv), debug=args.debug)


def _ended(error: BaseException) -> tuple[int, str]:
    """:func:`ending_of` for a command that now ends: after an interruption, a second Ctrl-C ends the process at
    once and the interruption counts as handled (the caller prints its line, and the launcher does not print it
    again).
    """
    code, line = ending_of(error)
    if code == INTERRUPTED:
        interrupts.ending()
    return code, line


class _LineFormatter(logging.Formatter):
    """A library's log record as one line: ``warning: ...`` (the level in lower case)."""

    def format(self, record):
        return f"{record.levelname.lower()}: {one_line(record.getMessage())}"


def _log_lines() -> None:
    """Log records of warnings and above from the libraries, as one line each on stderr (when nothing else
    handles them: an application that configured logging keeps its own).
    """
    root = logging.getLogger()
    if not root.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(_LineFormatter())
        handler.setLevel(logging.WARNING)
        root.addHandler(handler)


def run(work, debug: bool = False) -> int:
    """Call ``work()`` (it returns 0 or 1) and map what it raises to an exit code and one line on stderr.

    Python warnings of the libraries (numpy's ``RuntimeWarning`` on an overflow...) are not shown, since the
    checks of the result say what matters in one line; ``--debug`` shows them.
    """
    _log_lines()
    try:
        with _terminate_as_interrupt(), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always" if debug else "ignore")
            try:
                return work()
            finally:
                for warning in caught:  # --debug only (else none is recorded)
                    print(warnings.formatwarning(warning.message, warning.category, warning.filename,
                                                 warning.lineno, warning.line).rstrip(), file=sys.stderr)
    except (KeyboardInterrupt, Exception) as error:  # noqa: BLE001 - the contract: an exit code and one line
        code, line = _ended(error)
        if debug:
            traceback.print_exc()
        print(line, file=sys.stderr)
        return code


NO_SPACE = (errno.ENOSPC, errno.EDQUOT)
"""The errors of a full disk (or of a quota)."""


def ending_of(error: BaseException) -> tuple[int, str]:
    """The exit code and the stderr line of an exception that ended a command (:func:`run`).

    After a signal, any exception is the interruption's: a ``KeyboardInterrupt`` raised inside C code may come
    out as another error (numpy's C-extension import turns it into an ``ImportError``).
    """
    if isinstance(error, KeyboardInterrupt) or interrupts.interrupted():
        return INTERRUPTED, interrupts.INTERRUPTED_LINE
    if isinstance(error, FprError):
        return BAD_INPUT, f"error: {one_line(error)}"
    if isinstance(error, MemoryError):
        return BAD_INPUT, ("error: out of memory: ask for less work (a lower --rate, shorter --times, "
                           "fewer --via-points)")
    if isinstance(error, OSError):
        where = f" {error.filename}" if error.filename else ""
        if error.errno in NO_SPACE:
            return BAD_INPUT, (f"error: cannot write{where}: {error.strerror or error}: free some space on that "
                               "disk or give another --out")
        return BAD_INPUT, one_line(f"error: cannot read or write{where}: {error.strerror or error}: check the "
                                   "path and the free space")
    return INTERNAL_ERROR, one_line(f"internal error (a bug in fpr {fpr.__version__}): {type(error).__name__}: "
                                    f"{one_line(error, 300)}; {REPORT}", MAX_LINE + 300)
