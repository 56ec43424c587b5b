"""Reading a mission file: the bytes (a size cap, the encoding) and the TOML (guards against pathological
nesting), before :mod:`planners.missions.mission` checks the fields.

* :func:`read_mission_text`: at most :data:`MAX_FILE_BYTES` read (a device such as ``/dev/zero`` is not read to
  its end), UTF-8 with or without a byte-order mark; UTF-16/32 and other bytes are refused with what to do.
* :func:`parse_toml`: a key of more than :data:`MAX_KEY_DEPTH` dotted parts is refused before parsing (Python's
  TOML reader needs memory quadratic in their number: 400 MB for 10,000), arrays nested past the reader's
  recursion limit too.

Every refusal is a :class:`fpr.model.errors.MissionError` (field ``"<file>"`` or ``"<toml>"``).
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from fpr.model.errors import MissionError
from planners.missions import BUILTIN_MISSIONS

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: tomllib joined the standard library in 3.11; "tomli" is the same parser
    import tomli as tomllib

MAX_FILE_BYTES = 16 * 1024 * 1024
"""Largest mission file read [bytes]: 16 MiB. The planner's own limits (a 400 s mission checked at 500 Hz, travels
of at least 4 ms: 100,000 way points, about 8 MB of TOML for the FPR) refuse larger missions anyway; a larger
file (or a device such as ``/dev/zero``) is refused unread."""

MAX_KEY_DEPTH = 16
"""Most dotted parts of a TOML key a mission file may have (its own keys have at most 2)."""
_SEGMENT = r"""(?:[A-Za-z0-9_-]+|"[^"\n]*"|'[^'\n]*')"""
_DEEP_KEY = re.compile(rf"(?:{_SEGMENT}[ \t]*\.[ \t]*){{{MAX_KEY_DEPTH}}}{_SEGMENT}")

_BOMS = {b"\xff\xfe\x00\x00": "UTF-32", b"\x00\x00\xfe\xff": "UTF-32", b"\xff\xfe": "UTF-16",
         b"\xfe\xff": "UTF-16"}


def read_mission_text(path: str | os.PathLike) -> str:
    """The text of a mission file: UTF-8 (a leading byte-order mark is skipped), at most :data:`MAX_FILE_BYTES`.

    Raises:
        MissionError: a file that cannot be read, is larger than the limit (a device is not read to its
            end), or is not UTF-8 text (field ``"<file>"``, the message says what to do).
    """
    return read_toml_text(path, "mission", f"give the path of a .toml mission file or a built-in mission: "
                                           f"{', '.join(BUILTIN_MISSIONS)}")


def read_toml_text(path: str | os.PathLike, kind: str, hint: str) -> str:
    """The text of one of the toolkit's TOML files (``kind``: "mission", "campaign"), as
    :func:`read_mission_text` reads it; ``hint``: what to give instead, for the messages.

    Raises:
        MissionError: as :func:`read_mission_text` (field ``"<file>"``).
    """
    path = Path(path)
    source = str(path)
    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_FILE_BYTES + 1)
    except OSError as error:
        reason = f"cannot read {source!r} ({error.__class__.__name__}: {error.strerror or error}): {hint}"
        raise MissionError("<file>", reason, source) from error
    if len(data) > MAX_FILE_BYTES:
        raise MissionError("<file>", f"{source!r} is larger than {MAX_FILE_BYTES // (1024 * 1024)} MiB (a {kind} "
                                     f"file is a few kB): {hint}", source)
    for bom, encoding in _BOMS.items():
        if data.startswith(bom):
            raise MissionError("<file>", f"{source!r} is {encoding} text; TOML files are UTF-8: save it as UTF-8",
                               source)
    try:
        return data.decode("utf-8-sig")  # a byte-order mark (some Windows editors write one) is skipped
    except UnicodeDecodeError as error:
        line = data[:error.start].count(b"\n") + 1
        raise MissionError("<file>", f"{source!r} is not UTF-8 text (byte {error.start}, line {line}: "
                                     f"{error.reason}); TOML files are UTF-8: save it as UTF-8, or {hint}",
                           source) from None


def parse_toml(text: str, source: str = "") -> dict:
    """The TOML document ``text`` as a dictionary (a leading byte-order mark is skipped).

    Raises:
        MissionError: a TOML syntax error (field ``"<toml>"``, the reason gives line and column), a key of
            more than :data:`MAX_KEY_DEPTH` dotted parts, arrays or tables nested too deeply.
    """
    text = text.removeprefix("\ufeff")  # a byte-order mark, as some editors write
    deep = _DEEP_KEY.search(text)
    if deep is not None:  # tomllib needs memory quadratic in a dotted key's depth: refuse before parsing
        line = text.count("\n", 0, deep.start()) + 1
        raise MissionError("<toml>", f"a key of more than {MAX_KEY_DEPTH} dotted parts (line {line}); the keys of "
                                     "the toolkit's files have at most 2 (robot_parameters.link_length): see the "
                                     "format in planners/missions/mission.py", source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        reason = str(error)
        if "end of document" in reason:  # tomllib gives no line number there: add it
            reason += f" (line {text.count(chr(10)) + 1})"
        raise MissionError("<toml>", f"not valid TOML: {reason}; see the format in planners/missions/mission.py",
                           source) from error
    except RecursionError:
        raise MissionError("<toml>", "arrays or tables nested too deeply (a mission nests at most 3 levels: "
                                     "way_points = [[...], ...]): see the format in planners/missions/mission.py",
                           source) from None
    return data
