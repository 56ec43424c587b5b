"""Meshcat scenes of the FPR and its prototype: the robot, its planned and its tracked motion.

:func:`view` builds a :class:`SceneView` holding:

* the robot, drawn from its URDF visuals: the example-robot-data quadrotor meshes (hector body,
  iris propellers), the chain's rods, the end-effector, the prototype's fixed pivot and post;
  an axle on every revolute joint of the chain (the hinges);
* the ground plane z = -L (shared/DESIGN.md);
* with a plan (:class:`planners.optimize.PlanResult`): the robot follows the planned motion, red
  arrows show the planned thrusts, blue lines the paths of the end-effector and of the drones'
  centres, green spheres the way points and purple cubes the via points (at the mission's task
  point: the end-effector of the FPR, the drone joint of the prototype);
* with a simulation log (:class:`fpr.sim.closed_loop.SimulationLog`): the robot follows the simulated
  (tracked) motion with the controller's thrusts and orange paths, and a translucent blue "ghost"
  follows the plan (from ``plan`` when given, else from the reference recorded in the log);
* with ``configuration`` alone: the robot standing still.

Thrust arrows start at each drone's centre of mass and point along its body z axis, with
:data:`THRUST_SCALE` metres per newton (or ``thrust_scale``). Motions play as a meshcat animation
on the real time base (key frames at ``fps``, the last one at the exact end time).

Every body is placed by Pinocchio: the thesis coordinates q are mapped by
:meth:`fpr.model.robot.Robot.to_pinocchio`, forward kinematics runs on ``robot.model``, and the scene has
one node per joint, moved by that joint's world placement and holding the URDF visuals attached to
it (``pinocchio.buildGeomFromUrdfString`` with :func:`fpr.model.description.mesh_package_dirs`).

The scene is recorded as meshcat commands (the dictionaries meshcat's Python side sends to its
viewer) through a ``meshcat.Visualizer`` whose window records instead of sending: no server, no
process. :attr:`SceneView.html` replays them in a standalone page: meshcat's viewer script from the
installed package inline, then the commands (msgpack, base64) decoded and handed to the viewer.
The page loads nothing else (its content security policy forbids it): it opens from a file, offline,
and inside a Jupyter output (:meth:`SceneView._repr_html_`, an ``<iframe srcdoc>``). :func:`serve`
sends the same commands to a live meshcat server.

meshcat is optional: it is imported by the functions that need it, with an install hint.
"""

from __future__ import annotations

import base64
import contextlib
import html as html_lib
import io
import logging
import math
import uuid
import warnings
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from fpr.model import description
from fpr.model.errors import FprError, SceneError, check_shape

logger = logging.getLogger(__name__)

THRUST_SCALE = 0.03
"""Length of a thrust arrow per newton [m/N]: a hovering FPR drone (about 12 N) gets 0.36 m."""

DEFAULT_FPS = 30.0
"""Key frames per second of the animations [1/s]."""

EMBEDDED_MESH_LIMIT = 100_000
"""Collada meshes up to this size [bytes] (the drone body) are embedded as files, with their own
materials; larger ones (the propellers, 300 kB each) as Pinocchio's triangles, in one colour and
about a fifth of the size."""

ROOT = "/meshcat"
"""Where meshcat puts the scene; :class:`SceneView` accepts paths relative to it."""

_GHOST_COLOR, _GHOST_OPACITY = 0x3B8FE0, 0.3
_PLANNED_COLOR = 0x1F5FBF
_TRACKED_COLOR = 0xE07B00
_THRUST_COLOR = 0xD62728
_WAY_COLOR = 0x2CA02C
_VIA_COLOR = 0x9467BD
_HINGE_COLOR = 0x404048
_MESH_COLOR = 0x2A2A2A  # meshes without a URDF material: the propellers
_GROUND_COLOR = 0xC8D2C0

_CAMERA_FOV = 75.0  # meshcat's camera [deg, vertical]
_CAMERA_ASPECT = 4.0 / 3.0  # the framing holds in pages at least this wide

# three.js' cylinders are along y: turned onto z (URDF cylinders), and z onto x (the hinges' axles)
_CYLINDER_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])
_Z_TO_X = np.array([[0.0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]])


def _meshcat():
    """Import meshcat, or say how to install it."""
    try:
        with warnings.catch_warnings():  # meshcat 0.3.2 imports a module pyzmq deprecated
            warnings.filterwarnings("ignore", "zmq.eventloop.ioloop is deprecated", DeprecationWarning)
            import meshcat
            import meshcat.animation  # noqa: F401
            import meshcat.geometry  # noqa: F401
            import meshcat.visualizer  # noqa: F401
            import umsgpack  # noqa: F401  (meshcat's encoding of the commands)
    except ImportError as error:
        raise ImportError(f"fpr.views.scene needs meshcat ({error}): pip install meshcat") from error
    return meshcat


# ------------------------------------------------------------------------------------------ the view
@dataclass(eq=False)
class SceneView:
    """A recorded meshcat scene: shown inline by Jupyter, written as a page, or sent to a server.

    Attributes:
        commands: the meshcat commands in order (``set_object``, ``set_transform``, ``set_property``,
            ``set_animation`` dictionaries, as meshcat sends them to its viewer).
        title: the page's title.
        duration: length of the animation [s]; None for a static robot.
        fps: key frames per second of the animation [1/s].
        thrust_scale: length of the thrust arrows per newton [m/N].
        legend: lines of text drawn over the page.
        camera: (eye, target), where the page's camera starts and what it looks at (world) [m].
    """

    commands: list
    title: str
    duration: float | None
    fps: float
    thrust_scale: float
    legend: tuple = ()
    camera: tuple | None = None
    _html: str | None = field(default=None, repr=False)

    @staticmethod
    def _full(path: str) -> str:
        return path if path.startswith("/") else f"{ROOT}/{path}"

    @property
    def paths(self) -> list[str]:
        """Every node path that receives a command, in order of first appearance."""
        return list(dict.fromkeys(c["path"] for c in self.commands if c.get("path")))

    def object(self, path: str) -> dict:
        """The three.js object set at ``path`` (relative to /meshcat, or absolute)."""
        full = self._full(path)
        for command in reversed(self.commands):
            if command["type"] == "set_object" and command["path"] == full:
                return command["object"]
        raise KeyError(f"no object at {full!r}")

    def transform(self, path: str) -> np.ndarray:
        """The 4x4 transform set at ``path`` (for an animated node: its pose at t = 0)."""
        full = self._full(path)
        for command in reversed(self.commands):
            if command["type"] == "set_transform" and command["path"] == full:
                return np.array(command["matrix"], dtype=float).reshape(4, 4).T  # three.js: column-major
        raise KeyError(f"no transform at {full!r}")

    def track(self, path: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        """An animation track of ``path``: (times [s] (K,), values (K, 3) or (K, 4)).

        Args:
            path: node path (relative to /meshcat, or absolute).
            name: "position" [m], "quaternion" (x, y, z, w) or "scale".
        """
        full = self._full(path)
        for command in self.commands:
            for animation in command.get("animations", ()):
                if animation["path"] != full:
                    continue
                clip = animation["clip"]
                for track in clip["tracks"]:
                    if track["name"] == "." + name:
                        keys = track["keys"]
                        return (np.array([k["time"] for k in keys], dtype=float) / clip["fps"],
                                np.array([k["value"] for k in keys], dtype=float))
        raise KeyError(f"no {name!r} track at {full!r}")

    @property
    def html(self) -> str:
        """The standalone page (viewer script and scene inline; it requests nothing else)."""
        if self._html is None:
            self._html = _page(self)
        return self._html

    def write(self, path) -> Path:
        """Write :attr:`html` to ``path`` (a folder gets ``scene.html``); returns the file written."""
        path = Path(path)
        if path.is_dir():
            path = path / "scene.html"
        path.write_text(self.html, encoding="utf-8")
        logger.info("wrote %s", path)
        return path

    def _repr_html_(self) -> str:
        """Jupyter: the page in an ``<iframe srcdoc>``; needs no server, stays in saved notebooks."""
        return (f'<iframe srcdoc="{html_lib.escape(self.html, quote=True)}" '
                f'title="{html_lib.escape(self.title)}" style="width: 100%; height: 520px; border: none" '
                'allowfullscreen></iframe>')

    def send(self, visualizer) -> None:
        """Replay the commands into a ``meshcat.Visualizer`` (a live server)."""
        for command in self.commands:
            visualizer.window.send(_Lowered(command))

    def serve(self, zmq_url: str | None = None):
        """Send the scene to a live meshcat server; returns the ``meshcat.Visualizer`` (``.url()``).

        Args:
            zmq_url: a running server (``meshcat-server``); default: start one, a subprocess that
                meshcat stops when Python exits. Its camera looks at the world origin (the
                standalone page aims at the workspace).
        """
        meshcat = _meshcat()
        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL; the caller decides
            visualizer = meshcat.Visualizer(zmq_url=zmq_url)
        logger.info("meshcat server at %s", visualizer.url())
        self.send(visualizer)
        return visualizer


# ------------------------------------------------------------------------------------------ public API
def view(robot, plan=None, log=None, *, configuration=None, fps: float = DEFAULT_FPS,
         title: str | None = None, thrust_scale: float = THRUST_SCALE) -> SceneView:
    """Build the meshcat scene of a robot, a planned motion and / or a simulated one.

    Args:
        robot: the :class:`fpr.model.robot.Robot` (``plan.robot``, ``mission.load_robot()``).
        plan: a :class:`planners.optimize.PlanResult`. Alone: the robot follows it. With ``log``: the
            ghost follows it. Its way and via points are marked.
        log: a :class:`fpr.sim.closed_loop.SimulationLog`: the robot follows the simulated motion and a
            translucent ghost the plan.
        configuration: thesis coordinates q (n,) of a robot standing still (not with a plan or a
            log). With nothing given: FPR s0 = [0 0 5pi/4 pi/2], prototype xi = [0 pi/2].
        fps: key frames per second of the animation [1/s]; it plays in real time.
        title: the page's title (default: mission name, what is shown, duration).
        thrust_scale: length of the thrust arrows per newton [m/N].

    Returns:
        the :class:`SceneView` (``.html``, ``.write(path)``; Jupyter shows it inline).

    Raises:
        SceneError: a robot, plan or log of the wrong kind or for another robot, a configuration
            given with a plan or a log, a non-finite configuration, fps or thrust_scale not > 0.
        ShapeError: a configuration or log array of the wrong shape.
        ImportError: meshcat is not installed.
    """
    robot = _check_robot(robot)
    for name, value in (("fps", fps), ("thrust_scale", thrust_scale)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not (math.isfinite(value) and value > 0):
            raise SceneError(name, f"{value!r}: give a finite number > 0")
    if configuration is not None and (plan is not None or log is not None):
        raise SceneError("configuration", "it shows the robot standing still: give it alone, or a plan "
                                          "and / or a log instead")
    if plan is not None:
        _check_plan(robot, plan)
    if log is not None:
        _check_log(robot, log)

    scene = _Scene(robot, float(fps), float(thrust_scale))
    if plan is None and log is None:
        q = _default_configuration(robot) if configuration is None else \
            check_shape("configuration", configuration, (robot.nq,))
        if not np.all(np.isfinite(q)):
            raise SceneError("configuration", f"{np.array2string(q, precision=4)} is not finite")
        poses = scene.poses(q[None])
        scene.draw_robot("robot", poses, None, ghost=False)
        scene.environment([(poses, None)])
        return scene.view(title or f"{robot.name}: configuration", None, ())

    duration = max(([plan.trajectory.total_duration] if plan is not None else [])
                   + ([float(log.t[-1])] if log is not None else []))
    times = scene.frame_times = _frame_times(duration, scene.fps)
    planned = _planned_motion(robot, plan, times) if plan is not None \
        else _logged_reference(robot, log, times)
    planned_poses = scene.poses(planned.q)
    scale = f"{thrust_scale:g} m/N"
    if log is None:
        scene.draw_robot("robot", planned_poses, planned, ghost=False)
        scene.paths("planned", planned_poses, _PLANNED_COLOR)
        legend = ["robot: planned motion", f"red arrows: planned thrusts ({scale})",
                  "blue lines: planned paths of the end-effector and the drones"]
        everything = [(planned_poses, planned)]
    else:
        tracked = _tracked_motion(log, times)
        tracked_poses = scene.poses(tracked.q)
        scene.draw_robot("robot", tracked_poses, tracked, ghost=False)
        scene.draw_robot("ghost", planned_poses, planned, ghost=True)
        scene.paths("planned", planned_poses, _PLANNED_COLOR)
        scene.paths("tracked", tracked_poses, _TRACKED_COLOR)
        legend = ["solid robot: simulation; translucent: plan", f"red arrows: controller thrusts ({scale})",
                  "paths: planned (blue), simulated (orange)"]
        everything = [(planned_poses, planned), (tracked_poses, tracked)]
    if plan is not None:
        legend.append(scene.markers(plan))
    scene.environment(everything)
    name = getattr(getattr(plan, "mission", None), "name", None) or robot.name
    shown = "simulation" if log is not None else f"plan ({plan.method})"
    return scene.view(title or f"{name}: {shown}, {duration:g} s", duration, tuple(legend))


def write_scene(path, robot, plan=None, log=None, **kw) -> Path:
    """Write the page of :func:`view` to ``path`` (a folder gets ``scene.html``); returns the file written."""
    return view(robot, plan, log, **kw).write(path)


def serve(robot, plan=None, log=None, *, zmq_url: str | None = None, **kw):
    """Send the scene of :func:`view` to a live meshcat server; returns the ``meshcat.Visualizer``.

    Args:
        robot: as :func:`view`.
        plan: as :func:`view`.
        log: as :func:`view`.
        zmq_url: a running server (``meshcat-server``); default: start one.
        **kw: the keyword arguments of :func:`view`.

    Returns:
        the Visualizer (:meth:`SceneView.serve`); ``visualizer.url()`` is the page to open.
    """
    return view(robot, plan, log, **kw).serve(zmq_url)


# ------------------------------------------------------------------------------------------ inputs
@dataclass
class _Motion:
    """A motion at the frame times: q (N, n) thesis coordinates, thrust (N, n_d) [N] or None."""

    q: np.ndarray
    thrust: np.ndarray | None


def _check_robot(robot):
    from fpr.model.robot import Robot

    if not isinstance(robot, Robot):
        raise SceneError("robot", f"got a {type(robot).__name__}; give fpr.load('fpr'), "
                                  "fpr.load('prototype') or plan.robot")
    return robot


def _check_plan(robot, plan) -> None:
    if not all(hasattr(plan, a) for a in ("trajectory", "is_way", "method")):
        raise SceneError("plan", f"got a {type(plan).__name__}; give the PlanResult of "
                                 "planners.optimize.plan")
    other = getattr(plan, "robot", None)
    if other is not None and (other.name != robot.name or other.urdf != robot.urdf):
        raise SceneError("plan", f"it was planned for another robot ({other.name}, "
                                 f"L = {other.link_length:g} m) than the one given ({robot.name}, "
                                 f"L = {robot.link_length:g} m): give plan.robot")
    if len(plan.is_way) != len(plan.trajectory.points):
        raise SceneError("plan", f"{len(plan.is_way)} way/via flags for {len(plan.trajectory.points)} points")


def _check_log(robot, log) -> None:
    if not all(hasattr(log, a) for a in ("robot_name", "coordinates", "t", "q", "thrust", "reference",
                                         "planned_roll")):
        raise SceneError("log", f"got a {type(log).__name__}; give the SimulationLog of "
                                "fpr.sim.closed_loop.simulate")
    if log.robot_name != robot.name or tuple(log.coordinates) != tuple(robot.layout.coordinates):
        raise SceneError("log", f"it is a simulation of the {log.robot_name!r} (coordinates "
                                f"{', '.join(log.coordinates)}), not of the {robot.name!r} given")
    t = np.asarray(log.t, dtype=float)
    check_shape("log.q", log.q, (t.size, robot.nq))
    check_shape("log.thrust", log.thrust, (t.size, robot.n_drones))
    if t.size < 2 or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(log.q)):
        raise SceneError("log", "it needs at least two samples, increasing times and finite states")


def _default_configuration(robot) -> np.ndarray:
    if robot.name == "fpr":
        return robot.configuration(phi=5 * np.pi / 4, q21=np.pi / 2)
    return robot.configuration(q1=0.0, q2=np.pi / 2)


def _frame_times(duration: float, fps: float) -> np.ndarray:
    """k / fps for k = 0, 1, ..., then the duration itself (the animation's real time base) [s]."""
    t = np.arange(int(math.floor(duration * fps * (1.0 + 1e-12))) + 1) / fps
    if duration - t[-1] > 1e-9 * max(duration, 1.0):
        t = np.append(t, duration)
    t[-1] = duration
    return t


def _planned_motion(robot, plan, times: np.ndarray) -> _Motion:
    """The plan at ``times``, at rest on its last point after its end: full q and thrusts."""
    from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics

    motion = plan.trajectory.evaluate_held(times, order=MOTION_ORDER)  # 6: singularity crossing
    inputs = inverse_dynamics(robot, motion)
    return _Motion(inputs.full_state(robot)[0], inputs.thrust)


def _interpolate(t_from, values, t_to) -> np.ndarray:
    values = np.asarray(values, dtype=float).reshape(len(t_from), -1)
    return np.stack([np.interp(t_to, t_from, v) for v in values.T], axis=1)


def _tracked_motion(log, times: np.ndarray) -> _Motion:
    """The simulated state and the controller's thrusts at ``times`` (linear interpolation)."""
    return _Motion(_interpolate(log.t, log.q, times), _interpolate(log.t, log.thrust, times))


def _logged_reference(robot, log, times: np.ndarray) -> _Motion:
    """The plan as the log recorded it (chain coordinates and drone rolls); no thrusts."""
    q = np.zeros((len(log.t), robot.nq))
    q[:, robot.indices(robot.layout.chain)] = log.reference[0]
    q[:, robot.indices(robot.layout.rolls)] = log.planned_roll
    return _Motion(_interpolate(log.t, q, times), None)


# ------------------------------------------------------------------------------------------ kinematics
@dataclass
class _Poses:
    """World placements at N configurations."""

    joints: np.ndarray  # (N, n_j, 4, 4): joints carrying visuals or hinges, in _Scene.joint_ids order
    drones: np.ndarray  # (N, n_d, 4, 4): drone centres of mass
    end_effector: np.ndarray  # (N, 3)
    task_point: np.ndarray  # (N, 3): the mission's point (FPR: end-effector; prototype: drone joint)


_VISUAL_MODELS: dict = {}


def _visual_model(robot):
    """Pinocchio's visual geometry model of the robot's URDF (built once per URDF text)."""
    if robot.urdf not in _VISUAL_MODELS:
        try:
            geometry = pin.buildGeomFromUrdfString(robot.model, robot.urdf, pin.GeometryType.VISUAL,
                                                   package_dirs=description.mesh_package_dirs())
        except (ValueError, RuntimeError, OSError) as error:
            raise FprError(f"cannot load the robot's meshes ({error}); they come with example-robot-data: "
                           "pip install example-robot-data") from error
        if len(_VISUAL_MODELS) >= 8:
            _VISUAL_MODELS.clear()
        _VISUAL_MODELS[robot.urdf] = geometry
    return _VISUAL_MODELS[robot.urdf]


def _is_hinge(model, joint_id: int) -> bool:
    """A revolute joint about x: a joint of the planar chain, drawn as an axle."""
    return model.joints[joint_id].shortname() == "JointModelRX"


# ------------------------------------------------------------------------------------------ geometry
def _uuid() -> str:
    return str(uuid.uuid4())


def _matrix(transform: np.ndarray) -> list[float]:
    """A 4x4 transform in three.js' (column-major) order."""
    return [float(x) for x in np.asarray(transform, dtype=float).T.ravel()]


def _translation(p) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = p
    return t


def _rgb(rgba) -> int:
    r, g, b = (int(round(255 * float(np.clip(x, 0.0, 1.0)))) for x in rgba[:3])
    return (r << 16) | (g << 8) | b


@lru_cache(maxsize=8)
def _read_text(path: str) -> str:
    return Path(path).read_text(encoding="utf-8")


_MESHES: dict = {}


def _mesh_arrays(geometry_object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (already scaled by Pinocchio), faces and area-weighted vertex normals of a mesh visual."""
    key = (geometry_object.meshPath, tuple(geometry_object.meshScale))
    if key not in _MESHES:
        mesh = geometry_object.geometry
        vertices = np.asarray(mesh.vertices(), dtype=float)
        faces = np.array([[t[0], t[1], t[2]] for t in map(mesh.tri_indices, range(mesh.num_tris))],
                         dtype=np.uint32)
        a, b, c = (vertices[faces[:, i]] for i in range(3))
        normals = np.zeros_like(vertices)
        for i in range(3):
            np.add.at(normals, faces[:, i], np.cross(b - a, c - a))
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        _MESHES[key] = (vertices.astype(np.float32), faces, normals.astype(np.float32))
    return _MESHES[key]


class _Group:
    """A three.js group of meshes sharing geometries and materials: one ``set_object`` per body."""

    def __init__(self, name: str, color: int | None = None, opacity: float = 1.0):
        self.name = name
        self.color, self.opacity = color, opacity  # color: one for every mesh (the ghost)
        self.children: list[dict] = []
        self.geometries: dict = {}
        self.materials: dict = {}

    def geometry(self, key, make) -> str:
        if key not in self.geometries:
            self.geometries[key] = {"uuid": _uuid(), **make()}
        return self.geometries[key]["uuid"]

    def material(self, color: int) -> str:
        color = self.color if self.color is not None else color
        if color not in self.materials:
            import meshcat.geometry as mg

            material = mg.MeshPhongMaterial(color=color, opacity=self.opacity, transparent=self.opacity < 1,
                                            depthWrite=self.opacity >= 1)
            self.materials[color] = material.lower({})
        return self.materials[color]["uuid"]

    def mesh(self, name: str, geometry: str, color: int, matrix: np.ndarray) -> None:
        self.children.append({"uuid": _uuid(), "type": "Mesh", "name": name, "geometry": geometry,
                              "material": self.material(color), "matrix": _matrix(matrix)})

    def cylinder(self, name: str, length: float, radius: float, color: int, matrix: np.ndarray,
                 radius_top: float | None = None) -> None:
        """A cylinder (a cone with ``radius_top=0``) along z, centred on ``matrix``'s origin."""
        top = radius if radius_top is None else radius_top
        gid = self.geometry(("cylinder", length, radius, top), lambda: {
            "type": "CylinderGeometry", "radiusTop": top, "radiusBottom": radius, "height": length,
            "radialSegments": 32})
        self.mesh(name, gid, color, matrix @ _CYLINDER_TO_Z)

    def visual(self, geometry_object) -> None:
        """A URDF visual, in its joint's frame."""
        import coal
        import meshcat.geometry as mg

        shape, name = geometry_object.geometry, geometry_object.name
        placement = geometry_object.placement.homogeneous
        color = _rgb(geometry_object.meshColor) if geometry_object.overrideMaterial else _MESH_COLOR
        if isinstance(shape, coal.Sphere):
            gid = self.geometry(("sphere", shape.radius), lambda: {
                "type": "SphereGeometry", "radius": shape.radius, "widthSegments": 24, "heightSegments": 16})
            self.mesh(name, gid, color, placement)
        elif isinstance(shape, coal.Cylinder):
            self.cylinder(name, 2.0 * shape.halfLength, shape.radius, color, placement)
        elif isinstance(shape, coal.BVHModelBase):
            path = Path(geometry_object.meshPath)
            if (self.color is None and path.suffix.lower() == ".dae" and path.is_file()
                    and path.stat().st_size <= EMBEDDED_MESH_LIMIT):
                # the file itself, with its materials (three.js' Collada loader; metres, Z up)
                scale = np.diag(np.append(np.asarray(geometry_object.meshScale, dtype=float), 1.0))
                self.children.append({"uuid": _uuid(), "type": "_meshfile_object", "name": name,
                                      "format": "dae", "data": _read_text(str(path)), "resources": {},
                                      "matrix": _matrix(placement @ scale)})
                return

            def triangles():
                vertices, faces, normals = _mesh_arrays(geometry_object)
                return {"type": "BufferGeometry",
                        "data": {"attributes": {"position": mg.pack_numpy_array(vertices.T),
                                                "normal": mg.pack_numpy_array(normals.T)},
                                 "index": mg.pack_numpy_array(faces.T)}}

            self.mesh(name, self.geometry(("mesh", str(path), tuple(geometry_object.meshScale)), triangles),
                      color, placement)
        else:
            logger.warning("visual %s: %s geometries are not drawn", name, type(shape).__name__)

    def lower(self) -> dict:
        return {"metadata": {"version": 4.5, "type": "Object"},
                "geometries": list(self.geometries.values()), "materials": list(self.materials.values()),
                "object": {"uuid": _uuid(), "type": "Group", "name": self.name, "matrix": _matrix(np.eye(4)),
                           "children": self.children}}


# ------------------------------------------------------------------------------------------ recording
class _Recorder:
    """A meshcat window that keeps the commands instead of sending them to a server."""

    def __init__(self):
        self.commands: list[dict] = []

    def send(self, command) -> None:
        self.commands.append(command.lower())


class _Lowered:
    """A command already in meshcat's format, for ``window.send``."""

    def __init__(self, data: dict):
        self.data = data

    def lower(self) -> dict:
        return self.data


class _Scene:
    """Draws one scene into a recording ``meshcat.Visualizer``."""

    def __init__(self, robot, fps: float, thrust_scale: float):
        meshcat = _meshcat()
        self.mg = meshcat.geometry
        self.robot = robot
        self.fps = fps
        self.thrust_scale = thrust_scale
        self.recorder = _Recorder()
        self.vis = meshcat.Visualizer(window=self.recorder)
        self.animation = meshcat.animation.Animation(default_framerate=fps)
        self.frame_times: np.ndarray | None = None  # key frames [s], set for a motion
        self.animated = False
        self.visual_model = _visual_model(robot)
        model = robot.model
        carriers = {o.parentJoint for o in self.visual_model.geometryObjects}
        self.joint_ids = tuple(j for j in range(1, model.njoints) if j in carriers or _is_hinge(model, j))
        self.end_effector_frame = model.getFrameId("end_effector")
        if self.end_effector_frame >= model.nframes:
            raise FprError(f"the {robot.name} URDF has no 'end_effector' link")
        self.camera = (np.array([3.0, 0.0, 1.0]), np.zeros(3))

    def poses(self, q: np.ndarray) -> _Poses:
        """Forward kinematics of the Pinocchio model at each configuration q[k] (thesis coordinates)."""
        robot, model, data = self.robot, self.robot.model, self.robot.data
        n = len(q)
        joints = np.empty((n, len(self.joint_ids), 4, 4))
        drones = np.empty((n, robot.n_drones, 4, 4))
        end_effector, task = np.empty((n, 3)), np.empty((n, 3))
        for k in range(n):
            pin.framesForwardKinematics(model, data, robot.to_pinocchio(q[k]))
            for i, j in enumerate(self.joint_ids):
                joints[k, i] = data.oMi[j].homogeneous
            for i, f in enumerate(robot.drone_frame_ids):
                drones[k, i] = data.oMf[f].homogeneous
            end_effector[k] = data.oMf[self.end_effector_frame].translation
            task[k] = data.oMi[robot.hinge_joint_ids[0]].translation if robot.name == "prototype" \
                else end_effector[k]
        return _Poses(joints, drones, end_effector, task)

    def view(self, title: str, duration: float | None, legend: tuple) -> SceneView:
        if self.animated:
            self.vis.set_animation(self.animation, play=True, repetitions=1)
        return SceneView(self.recorder.commands, title, duration, self.fps, self.thrust_scale, legend,
                         self.camera)

    def set_group(self, path: str, group: _Group) -> None:
        """``set_object`` of a group (meshcat's own ``set_object`` takes one geometry)."""
        self.vis.window.send(_Lowered({"type": "set_object", "path": self.vis[path].path.lower(),
                                       "object": group.lower()}))

    def _place(self, path: str, transforms: np.ndarray) -> None:
        """The first pose, then one key frame per frame time if there are several poses."""
        self.vis[path].set_transform(transforms[0])
        if len(transforms) > 1:
            self.animated = True
            for k, t in enumerate(self.frame_times):
                self.animation.at_frame(self.vis, t * self.fps)[path].set_transform(transforms[k])

    # -------------------------------------------------------------- robot
    def draw_robot(self, prefix: str, poses: _Poses, motion: _Motion | None, ghost: bool) -> None:
        """The robot's bodies (one node per joint, plus the fixed base) and its thrust arrows."""
        model = self.robot.model
        color, opacity = (_GHOST_COLOR, _GHOST_OPACITY) if ghost else (None, 1.0)
        groups = {}
        for o in self.visual_model.geometryObjects:
            groups.setdefault(o.parentJoint, _Group(model.names[o.parentJoint], color, opacity)).visual(o)
        radius = 2.0 * float(self.robot.parameters["link_radius"])
        length = 2.5 * float(self.robot.parameters["end_effector_radius"])
        for j in self.joint_ids:
            if _is_hinge(model, j):
                group = groups.setdefault(j, _Group(model.names[j], color, opacity))
                group.cylinder("hinge", length, radius, _HINGE_COLOR, _Z_TO_X)
        for j, group in groups.items():
            path = f"{prefix}/{model.names[j]}" if j > 0 else f"{prefix}/base"
            self.set_group(path, group)
            if j > 0:
                self._place(path, poses.joints[:, self.joint_ids.index(j)])
        if motion is not None and motion.thrust is not None:
            self.thrust_arrows(prefix, poses, motion, ghost)

    def thrust_arrows(self, prefix: str, poses: _Poses, motion: _Motion, ghost: bool) -> None:
        """From each drone's centre of mass along its body z, ``thrust_scale`` metres per newton.

        The arrow's node sits on the drone's centre frame; its shaft (unit length) is stretched by
        the node ``shaft``'s scale, its head moved by the node ``head``'s position.
        """
        color, opacity = (_GHOST_COLOR, 0.45) if ghost else (_THRUST_COLOR, 1.0)
        shaft_radius, head_radius, head_length = 0.012, 0.03, 0.08
        length = np.maximum(self.thrust_scale * np.maximum(motion.thrust, 0.0), 1e-6)
        for i, drone in enumerate(self.robot.layout.drones):
            path = f"{prefix}/thrust/{drone}"
            for part, height, radius, top in (("shaft", 1.0, shaft_radius, None),
                                              ("head", head_length, head_radius, 0.0)):
                group = _Group(part, None, opacity)
                group.cylinder(part, height, radius, color, _translation([0, 0, height / 2]), radius_top=top)
                self.set_group(f"{path}/{part}", group)
            self._place(path, poses.drones[:, i])
            self.vis[f"{path}/shaft"].set_transform(np.diag([1.0, 1.0, length[0, i], 1.0]))
            self.vis[f"{path}/head"].set_transform(_translation([0, 0, length[0, i]]))
            for k, t in enumerate(self.frame_times):
                frame = self.animation.at_frame(self.vis, t * self.fps)
                frame[f"{path}/shaft"].set_property("scale", "vector3", [1.0, 1.0, float(length[k, i])])
                frame[f"{path}/head"].set_property("position", "vector3", [0.0, 0.0, float(length[k, i])])

    # -------------------------------------------------------------- paths, markers, environment
    def paths(self, name: str, poses: _Poses, color: int) -> None:
        """Lines through the end-effector's and the drones' centres' positions."""
        mg = self.mg
        lines = {"end_effector": poses.end_effector}
        lines.update({drone: poses.drones[:, i, :3, 3] for i, drone in enumerate(self.robot.layout.drones)})
        for part, points in lines.items():
            geometry = mg.PointsGeometry(np.asarray(points, dtype=np.float32).T)
            self.vis[f"paths/{name}/{part}"].set_object(mg.Line(geometry, mg.LineBasicMaterial(color=color)))

    def markers(self, plan) -> str:
        """Way points (spheres) and via points (cubes) at the task point; returns the legend line."""
        mg = self.mg
        knots = plan.trajectory.knots
        q = np.zeros((len(knots), self.robot.nq))
        q[:, self.robot.indices(self.robot.layout.chain)] = plan.trajectory.evaluate(knots, order=0)[0]
        points = self.poses(q).task_point
        is_way = np.asarray(plan.is_way, dtype=bool)
        for kind, flags, shape, color in (("way_points", is_way, mg.Sphere(0.035), _WAY_COLOR),
                                          ("via_points", ~is_way, mg.Box([0.045] * 3), _VIA_COLOR)):
            for n, point in enumerate(points[flags]):
                self.vis[f"markers/{kind}/{n}"].set_object(shape, mg.MeshPhongMaterial(color=color))
                self.vis[f"markers/{kind}/{n}"].set_transform(_translation(point))
        where = "drone joint" if self.robot.name == "prototype" else "end-effector"
        via = "; purple cubes: via points" if (~is_way).any() else ""
        return f"green spheres: way points ({where}){via}"

    def environment(self, shown: list[tuple[_Poses, _Motion | None]]) -> None:
        """The ground plane z = -L (meshcat's grid, at z = 0, hidden), the background, the camera."""
        mg = self.mg
        points = np.concatenate([_visible_points(p, m, self.thrust_scale) for p, m in shown])
        ground = -self.robot.link_length
        lo, hi = points.min(axis=0), points.max(axis=0)
        thickness, margin = 0.01, 1.0
        size = [hi[0] - lo[0] + 2 * margin, hi[1] - lo[1] + 2 * margin, thickness]
        self.vis["ground"].set_object(mg.Box(size), mg.MeshLambertMaterial(color=_GROUND_COLOR, opacity=0.85))
        self.vis["ground"].set_transform(_translation([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2,
                                                       ground - thickness / 2 - 1e-3]))
        self.vis["/Grid"].set_property("visible", False)
        self.vis["/Background"].set_property("top_color", [0.96, 0.97, 1.0])
        self.vis["/Background"].set_property("bottom_color", [0.72, 0.76, 0.82])
        # the camera frames the robot's motion (the ground shows below it)
        target = (lo + hi) / 2
        self.camera = (_camera_eye(points, target), target)
        # meshcat's camera looks at the origin, from a y-up frame where the world's (x, y, z) is (x, z, -y):
        # that is what a live server shows; the standalone page aims at the target (_page)
        eye = _camera_eye(points, np.zeros(3))
        self.vis["/Cameras/default/rotated/<object>"].set_property("position", [eye[0], eye[2], -eye[1]])


def _camera_eye(points: np.ndarray, target: np.ndarray, fill: float = 0.85) -> np.ndarray:
    """Where meshcat's camera (vertical fov 75 deg, z up) sees ``points`` within ``fill`` of a 4:3 page.

    The camera looks at ``target`` from +x, 15 deg to the right and 12 deg from above; its distance is
    found by bisection on the points' largest normalised image coordinate.
    """
    azimuth, elevation = math.radians(15.0), math.radians(12.0)
    back = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                     math.sin(elevation)])
    right = np.cross(-back, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -back)
    tan = math.tan(math.radians(_CAMERA_FOV / 2))

    def extent(distance: float) -> float:
        rel = points - (target + distance * back)
        depth = -(rel @ back)
        if depth.min() <= 0.05:
            return math.inf
        horizontal = np.abs(rel @ right / (depth * tan * _CAMERA_ASPECT)).max()
        return float(max(horizontal, np.abs(rel @ up / (depth * tan)).max()))

    near, far = 0.1, 1000.0
    for _ in range(60):
        middle = math.sqrt(near * far)
        near, far = (middle, far) if extent(middle) > fill else (near, middle)
    return target + far * back


def _visible_points(poses: _Poses, motion: _Motion | None, thrust_scale: float) -> np.ndarray:
    """Points the camera must see: joints, drones and their rotor discs, arrows' tips, end-effector."""
    centres = poses.drones[:, :, :3, 3]
    points = [poses.joints[:, :, :3, 3].reshape(-1, 3), poses.end_effector]
    for axis in (0, 1):
        for sign in (-1.0, 1.0):
            points.append((centres + sign * 0.27 * poses.drones[:, :, :3, axis]).reshape(-1, 3))
    if motion is not None and motion.thrust is not None:
        tips = centres + thrust_scale * np.maximum(motion.thrust, 0.0)[..., None] * poses.drones[:, :, :3, 2]
        points.append(tips.reshape(-1, 3))
    return np.concatenate(points)


# ------------------------------------------------------------------------------------------ the page
_CSP = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data: blob:; "
        "media-src data: blob:; font-src data:; connect-src data: blob:; worker-src blob:")


def _viewer_script() -> str:
    """meshcat's viewer (three.js, msgpack decoding, controls), from the installed package."""
    path = Path(_meshcat().__file__).parent / "viewer" / "dist" / "main.min.js"
    if not path.is_file():
        raise FprError(f"meshcat's viewer script {path} is missing: reinstall meshcat (pip install meshcat)")
    return _read_text(str(path)).replace("</script", "<\\/script")


def _page(scene: SceneView) -> str:
    """The standalone page: the viewer script, then the commands replayed into a viewer."""
    import umsgpack

    commands = ",\n".join(f'"{base64.b64encode(umsgpack.packb(c)).decode("ascii")}"' for c in scene.commands)
    legend = "".join(f"<div>{html_lib.escape(line)}</div>" for line in scene.legend)
    eye, target = ((0.0, 0.0, 0.0),) * 2 if scene.camera is None else scene.camera
    # three.js' frame of meshcat's camera is y up: the world's (x, y, z) is (x, z, -y) there
    eye, target = (", ".join(f"{float(x):.6g}" for x in (v[0], v[2], -v[1])) for v in (eye, target))
    aim = "" if scene.camera is None else f"""
  viewer.camera.position.set({eye});
  viewer.controls.target.set({target});
  viewer.controls.update();"""
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{_CSP}">
<title>{html_lib.escape(scene.title)}</title>
<style>
  body {{ margin: 0; }}
  #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
  #fpr-legend {{ position: absolute; left: 8px; top: 8px; padding: 4px 8px; pointer-events: none;
    font: 12px sans-serif; color: #222; background: rgba(255, 255, 255, 0.7); border-radius: 4px; }}
  #fpr-legend b {{ font-size: 13px; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="fpr-legend"><b>{html_lib.escape(scene.title)}</b>{legend}</div>
<script>
{_viewer_script()}
</script>
<script>
(function () {{
  var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  window.viewer = viewer;
  var commands = [
{commands}
  ];
  for (var i = 0; i < commands.length; i++) {{
    var text = atob(commands[i]);
    var bytes = new Uint8Array(text.length);
    for (var k = 0; k < text.length; k++) {{ bytes[k] = text.charCodeAt(k); }}
    viewer.handle_command_bytearray(bytes);
  }}{aim}
  viewer.set_dirty();
}})();
</script>
</body>
</html>
"""


__all__ = ["DEFAULT_FPS", "EMBEDDED_MESH_LIMIT", "ROOT", "SceneView", "THRUST_SCALE", "serve", "view",
           "write_scene"]
