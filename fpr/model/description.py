"""Robot descriptions: the xacro sources in ``urdf/`` and the URDFs generated from them.

The URDF is the single source of truth for geometry and inertia (shared/DESIGN.md). Its numbers come
from ``urdf/parameters.yaml``: each xacro file loads it and declares one xacro argument per value
it uses, with the yaml value as default, so ``generate_urdf("fpr", link_length=1.0)`` gives a
variant of the robot without editing any file.

Nothing here is specific to one robot: ``urdf/<name>.urdf.xacro`` generates ``urdf/<name>.urdf``, and a
robot outside the library passes the path of its own top-level xacro file (which may include the
library's macros, e.g. ``urdf/quadrotor.xacro``). Which robot uses which description is said by its
robot module (:mod:`fpr.robots`).

xacro runs without ROS, through xacrodoc. Mesh URIs stay ``package://example-robot-data/...`` in
the generated text, so that the committed URDFs do not depend on the machine; give
:func:`mesh_package_dirs` to Pinocchio (``package_dirs``) or yourdfpy to resolve them.

Regenerate the committed files with ``python -m fpr.model.description`` (``--check`` only compares; give
xacro paths to regenerate other descriptions).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import importlib.resources
import logging
import re
import sys
from pathlib import Path
from xml.dom import minidom

from fpr.model.errors import RobotDefinitionError, UnknownRobotError

logger = logging.getLogger(__name__)

_MESH_PACKAGE = "example-robot-data"
_XACRO_SUFFIX = ".urdf.xacro"


def _find_urdf_dir() -> Path:
    """Return the ``urdf/`` folder: beside the ``fpr`` package, else the installed ``urdf`` package."""
    here = Path(__file__).resolve().parents[2] / "urdf"
    if here.is_dir():
        return here
    try:
        return Path(str(importlib.resources.files("urdf")))
    except ModuleNotFoundError:  # not installed either: keep the source-tree path for error messages
        return here


URDF_DIR: Path = _find_urdf_dir()
"""The folder holding the library's xacro sources, ``parameters.yaml`` and the generated URDFs."""


def descriptions() -> tuple[str, ...]:
    """Return the names of the robot descriptions in ``urdf/``: every ``<name>.urdf.xacro`` file there.

    Returns:
        The sorted names, e.g. ``("fpr", "prototype")``.
    """
    return tuple(sorted(p.name[: -len(_XACRO_SUFFIX)] for p in URDF_DIR.glob("*" + _XACRO_SUFFIX)))


DESCRIPTIONS: tuple[str, ...] = descriptions()
"""Names of the robot descriptions in ``urdf/`` (``urdf/<name>.urdf.xacro`` -> ``urdf/<name>.urdf``)."""


def _is_path(robot) -> bool:
    """Whether ``robot`` is a file path rather than the name of a description in ``urdf/``."""
    return isinstance(robot, Path) or "/" in str(robot) or str(robot).endswith(".xacro")


def xacro_path(robot: str | Path) -> Path:
    """Return the top-level xacro file of a robot.

    Args:
        robot: the name of a description in ``urdf/`` (one of :data:`DESCRIPTIONS`), or the path of a
            top-level xacro file anywhere (a robot outside the library brings its own).

    Returns:
        ``urdf/<robot>.urdf.xacro``, or the path given.

    Raises:
        UnknownRobotError: ``robot`` is a name with no ``urdf/<robot>.urdf.xacro``.
        RobotDefinitionError: ``robot`` is a path to no file.
    """
    if _is_path(robot):
        path = Path(robot)
        if not path.is_file():
            raise RobotDefinitionError(str(path), "no such xacro file: give the path of a top-level .urdf.xacro file")
        return path
    path = URDF_DIR / f"{robot}{_XACRO_SUFFIX}"
    if not path.is_file():
        raise UnknownRobotError(str(robot), descriptions())
    return path


def urdf_path(robot: str | Path) -> Path:
    """Return the generated URDF file of a robot: its xacro file's path with ``.urdf`` for ``.urdf.xacro``.

    Args:
        robot: the name of a description in ``urdf/`` or the path of a top-level xacro file (see
            :func:`xacro_path`).

    Returns:
        ``urdf/<robot>.urdf`` (committed for the library's robots), or ``<folder>/<name>.urdf`` beside the
        xacro file given.

    Raises:
        UnknownRobotError: ``robot`` is a name with no ``urdf/<robot>.urdf.xacro``.
    """
    path = xacro_path(robot)
    name = path.name[: -len(_XACRO_SUFFIX)] if path.name.endswith(_XACRO_SUFFIX) else path.stem
    return path.with_name(name + ".urdf")


UNWRAPPED_ANGLE_LIMIT = 1.0e9
"""The position limit [rad] :func:`single_angle_urdf` gives a continuous joint: never reached, never enforced."""


def single_angle_urdf(urdf: str) -> str:
    """Return the URDF text with every ``continuous`` joint written as a ``revolute`` one, for Pinocchio.

    The passive hinges of the chain are ``continuous`` in the URDF: they have no angle limit, and other
    readers (MuJoCo, yourdfpy, RViz) see none. Pinocchio, however, gives a continuous joint two
    configuration coordinates (cos, sin of its angle; ``nq = 2``, ``nv = 1``), while every model of this
    project uses one unwrapped angle per hinge (``nq = nv``). A revolute joint with the limits
    ``+-UNWRAPPED_ANGLE_LIMIT`` is that coordinate; Pinocchio's dynamics never enforce a limit.

    Args:
        urdf: the URDF text.

    Returns:
        The same text with ``type="continuous"`` joints replaced (everything else byte for byte).
    """

    def revolute(match: re.Match) -> str:
        joint = match.group(0).replace('type="continuous"', 'type="revolute"', 1)
        limit = f'<limit lower="{-UNWRAPPED_ANGLE_LIMIT:g}" upper="{UNWRAPPED_ANGLE_LIMIT:g}" effort="0" velocity="0"/>'
        if "<limit" in joint:
            return re.sub(r"<limit\b[^>]*/>", limit, joint, count=1)
        return joint.replace("</joint>", limit + "</joint>", 1)

    return re.sub(r"<joint\b[^>]*\btype=\"continuous\"[^>]*>.*?</joint>", revolute, urdf, flags=re.S)


def xacro_arguments(xacro: str | Path | None = None) -> tuple[str, ...]:
    """Return the names of the xacro arguments the robot descriptions accept.

    They are the ``<xacro:arg name=...>`` declared in ``urdf/*.xacro`` (each is a key of
    ``urdf/parameters.yaml`` whose value is its default), plus, for a robot outside the library,
    those declared in the xacro files of its own folder.

    Args:
        xacro: a robot name or top-level xacro path (see :func:`xacro_path`), or None for the library's.

    Returns:
        The sorted argument names.
    """
    folders = [URDF_DIR]
    if xacro is not None and _is_path(xacro):
        folders.append(xacro_path(xacro).parent)
    names: set[str] = set()
    for folder in dict.fromkeys(folders):
        for path in sorted(folder.glob("*.xacro")):
            names.update(re.findall(r"<xacro:arg\s+name=\"(\w+)\"", path.read_text(encoding="utf-8")))
    return tuple(sorted(names))


def _robot_name(path: Path) -> str:
    """Return the ``name`` attribute of the root ``<robot>`` element of a xacro file."""
    root = minidom.parse(str(path)).documentElement
    if root.tagName != "robot" or not root.getAttribute("name"):
        raise RobotDefinitionError(str(path), "the root element must be <robot name=...>")
    return root.getAttribute("name")


def _format_arg(value) -> str:
    """Return a xacro argument value as text (``repr`` keeps every digit of a float)."""
    if isinstance(value, bool):
        raise TypeError("xacro arguments of the robot descriptions are numbers, not booleans")
    return repr(float(value)) if isinstance(value, (int, float)) else str(value)


def generate_urdf(robot: str | Path, **xacro_args) -> str:
    """Run xacro on a robot's top-level file (without ROS) and return the URDF text.

    Mesh URIs are kept as ``package://example-robot-data/...`` (not resolved to paths of this
    machine), so the text is machine independent.

    Args:
        robot: the name of a description in ``urdf/`` or the path of a top-level xacro file (see
            :func:`xacro_path`).
        **xacro_args: values overriding the defaults of ``urdf/parameters.yaml``, e.g.
            ``link_length=1.0``; see :func:`xacro_arguments` for the accepted names.

    Returns:
        The URDF document, starting with a banner saying where it comes from.

    Raises:
        UnknownRobotError: unknown robot name.
        RobotDefinitionError: unknown xacro argument, or no such xacro file.
    """
    # Imported here: xacrodoc patches xacro's package look-up at import time, and most users of
    # fpr only read the committed URDFs.
    from xacrodoc import XacroDoc

    path = xacro_path(robot)
    known = xacro_arguments(robot)
    unknown = sorted(set(xacro_args) - set(known))
    if unknown:
        raise RobotDefinitionError(
            str(robot), f"unknown xacro argument(s) {', '.join(unknown)}: use some of {', '.join(known)}"
        )
    subargs = {name: _format_arg(value) for name, value in xacro_args.items()}
    logger.debug("running xacro on %s with %s", path, subargs)

    # The top-level file is included (by absolute path) rather than read with
    # XacroDoc.from_file: from_file compiles the file's *text*, so xacro would resolve the
    # relative paths inside it (includes, load_yaml('parameters.yaml')) against the current
    # working directory instead of urdf/ ($(dirname) is not available either). An include pushes
    # the file on xacro's file stack, which makes them relative to the file, as with the xacro
    # command line. Only the root <robot> attributes are lost: the name is passed back.
    # (xacro fills the defaults into the dict it is given: give it a copy.)
    doc = XacroDoc.from_includes(
        [path.as_posix()],
        name=_robot_name(path),
        subargs=dict(subargs),
        resolve_packages=False,  # keep package:// URIs: the committed files are machine independent
    )

    source = f"urdf/{path.name}" if path.parent.resolve() == URDF_DIR.resolve() else path.as_posix()
    banner = f" Generated from {source} and urdf/parameters.yaml by `python -m fpr.model.description`"
    if subargs:
        banner += " with " + " ".join(f"{k}:={v}" for k, v in sorted(subargs.items()))
    banner += ". Do not edit by hand. "
    doc.dom.insertBefore(doc.dom.createComment(banner), doc.dom.documentElement)
    return doc.to_urdf_string(pretty=True)


def write_urdf(robot: str | Path, path: str | Path | None = None, **xacro_args) -> Path:
    """Generate a robot's URDF and write it to a file.

    Args:
        robot: the name of a description in ``urdf/`` or the path of a top-level xacro file.
        path: where to write; default: :func:`urdf_path` (``urdf/<robot>.urdf`` for the library's).
        **xacro_args: overrides of the ``urdf/parameters.yaml`` defaults (see :func:`generate_urdf`).

    Returns:
        The path written.
    """
    path = urdf_path(robot) if path is None else Path(path)
    text = generate_urdf(robot, **xacro_args)
    path.write_text(text, encoding="utf-8")
    logger.info("wrote %s", path)
    return path


def _candidate_share_dirs() -> list[Path]:
    """Return the folders that may hold ``example-robot-data/`` (the package's ``share`` folder)."""
    candidates: list[Path] = []
    try:  # pip / cmeel wheel: the files are recorded in the distribution
        dist = importlib.metadata.distribution(_MESH_PACKAGE)
    except importlib.metadata.PackageNotFoundError:
        dist = None
    if dist is not None:
        for file in dist.files or ():
            parts = file.parts
            if _MESH_PACKAGE in parts:
                rel = Path(*parts[: parts.index(_MESH_PACKAGE)])
                candidates.append(Path(str(dist.locate_file(rel))))
                break
    # other layouts: cmeel prefix in a site-packages folder, conda / robotpkg share folders
    for entry in sys.path:
        if entry:
            candidates.append(Path(entry) / "cmeel.prefix" / "share")
    for prefix in dict.fromkeys((sys.prefix, sys.base_prefix)):
        candidates.append(Path(prefix) / "share")
    return candidates


def mesh_package_dirs() -> list[str]:
    """Return the folders in which ``package://example-robot-data/...`` mesh URIs resolve.

    Give them to Pinocchio (``buildGeomFromUrdf(..., package_dirs=...)``) or use them to resolve
    the URIs for yourdfpy. The folder is the ``share`` folder of the installed example-robot-data
    (for the pip wheel: ``<site-packages>/cmeel.prefix/share``), found from the installed
    distribution and the Python search path.

    Returns:
        The folders (as strings, without duplicates) that contain ``example-robot-data/robots``;
        empty if example-robot-data is not installed.
    """
    found: list[str] = []
    for share in _candidate_share_dirs():
        try:
            ok = (share / _MESH_PACKAGE / "robots").is_dir()
        except OSError:
            ok = False
        if ok:
            text = str(share.resolve())
            if text not in found:
                found.append(text)
    if not found:
        logger.warning("%s is not installed: the robots' meshes cannot be shown", _MESH_PACKAGE)
    return found


def main(argv: list[str] | None = None) -> int:
    """Regenerate the committed URDFs (or, with ``--check``, compare them with their sources).

    Args:
        argv: command-line arguments (default: ``sys.argv[1:]``).

    Returns:
        The exit status: 0, or 1 if ``--check`` found a stale file.
    """
    parser = argparse.ArgumentParser(
        prog="python -m fpr.model.description",
        description="Regenerate the URDFs (urdf/<name>.urdf) from their xacro sources (urdf/<name>.urdf.xacro).",
    )
    parser.add_argument(
        "xacro",
        nargs="*",
        help="top-level xacro files to regenerate (each writes <name>.urdf beside it); default: every "
             "urdf/*.urdf.xacro",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="do not write: exit with status 1 if a committed URDF differs from its sources",
    )
    args = parser.parse_args(argv)

    status = 0
    for robot in args.xacro or descriptions():
        path = urdf_path(robot)
        text = generate_urdf(robot)
        if args.check:
            current = path.read_text(encoding="utf-8") if path.exists() else None
            if current == text:
                print(f"{path}: up to date")
            else:
                print(f"{path}: differs from its xacro sources (run python -m fpr.model.description)")
                status = 1
        else:
            path.write_text(text, encoding="utf-8")
            print(f"wrote {path}")
    return status


if __name__ == "__main__":
    sys.exit(main())
