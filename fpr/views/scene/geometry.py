"""The robot's looks for meshcat: its URDF visuals (Pinocchio's visual model of the URDF, with the
example-robot-data meshes) turned into three.js groups with their materials, and the small transforms
and encodings meshcat wants (column-major matrices, colours as integers).

meshcat is optional: :func:`_meshcat` imports it, or says how to install it.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import types
import uuid
import warnings
from functools import lru_cache
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from fpr.model import description
from fpr.model.errors import FprError

logger = logging.getLogger(__name__)

EMBEDDED_MESH_LIMIT = 100_000
"""Collada meshes up to this size [bytes] (the drone body) are embedded as files, with their own
materials; larger ones (the propellers, 300 kB each) as Pinocchio's triangles, in one colour and
about a fifth of the size."""

_HINGE_COLOR = 0x404048  # the axles drawn on the chain's revolute joints
_MESH_COLOR = 0x2A2A2A  # meshes without a URDF material: the propellers

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


_REVOLUTE_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}


def _revolute_axis(model, joint_id: int) -> np.ndarray | None:
    """The axis of a 1-DoF revolute joint in its own frame (unit), or None for any other joint."""
    joint = model.joints[joint_id]
    name = joint.shortname()
    if name in _REVOLUTE_AXES:
        return np.array(_REVOLUTE_AXES[name])
    if name in ("JointModelRevoluteUnaligned", "JointModelRevoluteUnboundedUnaligned"):
        axis = np.asarray(joint.extract().axis if hasattr(joint, "extract") else joint.axis, dtype=float)
        return axis / np.linalg.norm(axis)
    return None


def _is_hinge(model, joint_id: int) -> bool:
    """A 1-DoF revolute joint (about any axis): drawn as an axle."""
    return _revolute_axis(model, joint_id) is not None


def _axle_matrix(model, joint_id: int) -> np.ndarray:
    """The 4x4 transform that turns a cylinder along z onto a revolute joint's axis (:data:`_Z_TO_X` for an axis
    along x, the planar chain's).
    """
    axis = _revolute_axis(model, joint_id)
    if axis[0] == 1.0 and not axis[1:].any():
        return _Z_TO_X
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(z, axis), float(z.dot(axis))
    if np.linalg.norm(v) < 1e-12:  # along +-z
        rotation = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:  # Rodrigues: the rotation of z onto the axis
        k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
        rotation = np.eye(3) + k + k @ k / (1.0 + c)
    out = np.eye(4)
    out[:3, :3] = rotation
    return out


# ------------------------------------------------------------------------------------------ geometry
_ids = None  # the ids of the scene being built (deterministic_ids), or None: random ones


def _uuid() -> str:
    return str(uuid.uuid4()) if _ids is None else str(uuid.UUID(int=next(_ids)))


@contextlib.contextmanager
def deterministic_ids():
    """Within the block, the three.js objects' ids (ours and meshcat's own) are numbered 1, 2, ... in the order they
    are made, instead of random: the same scene gives the same bytes.
    """
    global _ids
    geometry = _meshcat().geometry
    previous, previous_module = _ids, geometry.uuid
    counter = _ids = itertools.count(1)

    def numbered(*_args, **_kwargs):
        return uuid.UUID(int=next(counter))

    geometry.uuid = types.SimpleNamespace(uuid1=numbered, uuid4=numbered)  # what meshcat.geometry calls
    try:
        yield
    finally:
        _ids, geometry.uuid = previous, previous_module


def _matrix(transform: np.ndarray) -> list[float]:
    """A 4x4 transform in three.js' (column-major) order."""
    return [float(x) for x in np.asarray(transform, dtype=float).T.ravel()]


def _translation(p) -> np.ndarray:
    """The 4x4 transform of a translation by p (3,) [m]."""
    t = np.eye(4)
    t[:3, 3] = p
    return t


def _rgb(rgba) -> int:
    """An RGBA colour in [0, 1] as three.js' 0xRRGGBB integer (alpha dropped)."""
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

