"""The output folder of a command line, written atomically, and its ``manifest.json``.

A run writes into a temporary folder beside ``--out`` (:meth:`OutputFolder.open`) and swaps it in only when
complete (:meth:`OutputFolder.commit`): the previous folder is renamed aside, the new one renamed to
``--out``, then the previous one deleted; if the second rename fails the previous folder is put back. A run
that fails or is interrupted calls :meth:`OutputFolder.discard`: the partial folder is removed and ``--out``
stays exactly as it was. A folder therefore always holds one run, described by its ``manifest.json``
(:func:`manifest`).

An existing ``--out`` is replaced only if it is empty or holds a previous run (a ``manifest.json``, or the
``mission.toml`` and ``plan.json`` of a run written before manifests existed): ``--out .`` or ``--out ~``
cannot delete a folder of yours.

Before the work, :meth:`OutputFolder.check_space` compares the disk's free space with the size the run will
write (estimated by the command); a disk that fills up during the run ends it with an :class:`OutputError`
naming ``--out`` and the space needed (:meth:`OutputFolder.no_space`).

The same command gives the same bytes: wall-clock times go to ``manifest.json`` only, and NumPy ``.npz`` files
are written by :func:`write_deterministic_npz` (fixed zip timestamps, no wall time).
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import io
import json
import os
import shutil
import signal
import tempfile
import threading
import zipfile
from pathlib import Path

import numpy as np

import fpr
from fpr.cli.interrupts import raise_if_interrupted
from fpr.model.errors import FprError

MANIFEST = "manifest.json"
_PREVIOUS_RUN_FILES = (("manifest.json",), ("mission.toml", "plan.json"), ("studies.json",))


class OutputError(FprError, OSError):
    """An output folder that cannot be written (an existing file, a folder that does not hold a run,
    a read-only or pseudo file system, a name too long, a full disk).

    Attributes:
        path: the ``--out`` folder concerned.
        reason: what is wrong and what to do.
    """

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"--out {self.path}: {reason}")


def _why(error: OSError) -> str:
    return error.strerror or str(error)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _holds_a_run(folder: Path) -> bool:
    names = {p.name for p in folder.iterdir()}
    return not names or any(all(n in names for n in group) for group in _PREVIOUS_RUN_FILES)


class OutputFolder:
    """A run's output: a temporary folder beside ``path``, swapped in by :meth:`commit`.

    Attributes:
        path: the final folder (``--out``), absolute.
        tmp: the temporary folder the run writes into (None before :meth:`open` and after commit/discard).
    """

    def __init__(self, path):
        self.path = Path(os.path.abspath(os.fspath(path)))
        self.tmp: Path | None = None
        self._created: list[Path] = []  # parent folders this run created (removed again on discard)

    def open(self) -> Path:
        """Check ``path`` and create the temporary folder beside it; returns the temporary folder.

        Raises:
            OutputError: ``path`` is a file, a folder that holds something else than a run, under a file,
                on a read-only or pseudo file system, or its name is too long.
        """
        path, parent = self.path, self.path.parent
        try:
            limit = os.pathconf(parent if parent.is_dir() else "/", "PC_NAME_MAX")
        except (OSError, ValueError):
            limit = 255
        too_long = [p.name for p in (path, *path.parents) if len(os.fsencode(p.name)) > limit]
        if too_long:
            raise OutputError(path, f"a folder name has {len(os.fsencode(too_long[0]))} bytes; this file system "
                                    f"allows {limit}: give a shorter name")
        if path.exists() and not path.is_dir():
            raise OutputError(path, "is an existing file: give the path of a folder (it is created)")
        try:
            foreign = path.is_dir() and not _holds_a_run(path)
        except OSError as error:
            raise OutputError(path, f"cannot read the folder ({_why(error)}): give another folder") from None
        if foreign:
            raise OutputError(path, "is a folder that does not hold an fpr run (no manifest.json): give a new "
                                    "or empty folder, or delete this one")
        missing = [p for p in [parent, *parent.parents] if not p.exists()]
        try:
            for folder in reversed(missing):
                folder.mkdir()
                self._created.append(folder)
            self.tmp = Path(tempfile.mkdtemp(prefix=f".{path.name[:40]}.tmp-", dir=parent))
            os.chmod(self.tmp, 0o777 & ~_umask())  # mkdtemp makes it private; a run's folder is not
        except OSError as error:
            self._remove_created()
            raise OutputError(path, f"cannot create a folder there ({_why(error)}): give a folder on a "
                                    "writable disk") from None
        return self.tmp

    def commit(self) -> None:
        """Swap the temporary folder in as ``path``; the previous folder is deleted once the swap succeeded.

        Ctrl-C is held back until the swap is over (then raised), so that it cannot leave ``path`` missing.

        Raises:
            OutputError: a rename failed (the previous folder is left in place, the temporary one removed).
        """
        if self.tmp is None:
            raise RuntimeError("OutputFolder.commit before open")
        raise_if_interrupted()
        with _interrupts_held():
            old = None
            try:
                if self.path.exists():
                    old = Path(tempfile.mkdtemp(prefix=f".{self.path.name[:40]}.old-", dir=self.path.parent))
                    os.rename(self.path, old / "run")
                try:
                    os.rename(self.tmp, self.path)
                except OSError:
                    if old is not None:
                        os.rename(old / "run", self.path)
                    raise
            except OSError as error:
                self.discard()
                if old is not None:
                    shutil.rmtree(old, ignore_errors=True)
                raise OutputError(self.path, f"cannot replace the folder ({_why(error)}): the previous one is "
                                             "left as it was") from None
            self.tmp = None
            if old is not None:
                shutil.rmtree(old, ignore_errors=True)

    def discard(self) -> None:
        """Remove the temporary folder (and the parent folders :meth:`open` created); ``path`` is untouched.

        Ctrl-C and SIGTERM are held back until it is done (then raised), so that no partial folder is left.
        """
        with _interrupts_held():
            if self.tmp is not None:
                shutil.rmtree(self.tmp, ignore_errors=True)
                self.tmp = None
            self._remove_created()

    def check_space(self, needed: float) -> None:
        """Refuse a run that would not fit on the disk of ``path``.

        Args:
            needed: the size the run will write, estimated [bytes].

        Raises:
            OutputError: less free space than ``needed`` (the message gives both).
        """
        folder = next((p for p in (self.path, *self.path.parents) if p.exists()), None)
        try:
            free = shutil.disk_usage(folder).free if folder is not None else None
        except OSError:
            free = None
        if free is not None and free < needed:
            raise OutputError(self.path, f"the disk has {size_text(free)} free; this run writes about "
                                         f"{size_text(needed)}: free some space or give an --out on another disk")

    def no_space(self, error: OSError, needed: float) -> OutputError:
        """The error to raise when the disk filled up during the run (``error``: the ``OSError``)."""
        return OutputError(self.path, f"the disk is full ({_why(error)}); this run writes about "
                                      f"{size_text(needed)}: free some space or give an --out on another disk")

    def _remove_created(self) -> None:
        for folder in reversed(self._created):
            with contextlib.suppress(OSError):
                folder.rmdir()
        self._created = []


@contextlib.contextmanager
def _interrupts_held():
    """Defer SIGINT (Ctrl-C) and SIGTERM until the block is over, then raise KeyboardInterrupt (main thread
    only).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    previous = {sig: signal.signal(sig, lambda *a: received.append(a)) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if received:
        raise KeyboardInterrupt


def size_text(n: float) -> str:
    """A size in bytes as a person reads it (``"3.2 MB"``)."""
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000:
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"


_ZIP_TIME = (1980, 1, 1, 0, 0, 0)  # the earliest a zip entry can hold: the same for every run


def write_deterministic_npz(path, source, replace: dict | None = None) -> None:
    """Write a NumPy ``.npz`` file that is the same bytes for the same arrays, whenever it is written.

    NumPy's ``savez`` stamps every entry of the zip with the time of writing; this writes the entries with a
    fixed time and mode, compressed.

    Args:
        path: the file to write.
        source: a function that writes an ``.npz`` into the file object it is given (e.g. a log's ``save``).
        replace: arrays to store instead of the source's entries of the same name (e.g. a wall time as NaN).
    """
    buffer = io.BytesIO()
    source(buffer)
    buffer.seek(0)
    replace = {f"{name}.npy": value for name, value in (replace or {}).items()}
    with zipfile.ZipFile(buffer) as read, zipfile.ZipFile(path, "w") as written:
        for entry in read.infolist():
            data = read.read(entry.filename)
            if entry.filename in replace:
                array = io.BytesIO()
                np.lib.format.write_array(array, np.asanyarray(replace[entry.filename]), allow_pickle=False)
                data = array.getvalue()
            info = zipfile.ZipInfo(entry.filename, date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            written.writestr(info, data)


def inputs_hash(mission_text: str, options: dict) -> str:
    """SHA-256 of what determines a run's results: the mission as planned (TOML) and the options."""
    document = json.dumps({"mission": mission_text, "options": options}, sort_keys=True, default=str)
    return hashlib.sha256(document.encode("utf-8")).hexdigest()


def manifest(command: list[str], inputs_sha256: str, started: float, duration: float, exit_code: int,
             outcome: str, files: list[str], timings: dict) -> dict:
    """The content of ``manifest.json``.

    Args:
        command: the command line, program first.
        inputs_sha256: :func:`inputs_hash` of the run.
        started: start time, seconds since the epoch (written as UTC ISO 8601).
        duration: wall time of the run [s].
        exit_code: the run's exit code (0 or 1: a failed run leaves no folder).
        outcome: one line saying what the run found.
        files: the files of the folder, manifest aside.
        timings: wall-clock times of the stages [s] (kept out of the other files, so that they are
            byte-identical from one run to the next).
    """
    start = datetime.datetime.fromtimestamp(started, tz=datetime.timezone.utc)
    return {
        "command": list(command),
        "fpr_version": fpr.__version__,
        "inputs_sha256": inputs_sha256,
        "started_utc": start.isoformat(timespec="seconds"),
        "duration_s": round(duration, 3),
        "exit_code": exit_code,
        "outcome": outcome,
        "files": sorted(files),
        "timings_s": timings,
    }


def write_manifest(folder: Path, document: dict) -> None:
    """Write ``manifest.json`` into ``folder``."""
    (folder / MANIFEST).write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
