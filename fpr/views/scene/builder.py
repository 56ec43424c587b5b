"""Draws one meshcat scene: the robot (and its ghost) placed by Pinocchio at every key frame, the thrust
arrows, the paths, the way / via point markers, the ground and the camera, as a meshcat animation.

Every body is placed by Pinocchio: the thesis coordinates q are mapped by
:meth:`fpr.model.robot.Robot.to_pinocchio`, forward kinematics runs on ``robot.model``, and the scene has
one node per joint, moved by that joint's world placement and holding the URDF visuals attached to
it (:mod:`fpr.views.scene.geometry`). The motions drawn come from a plan (inverse dynamics at the key
frames), a simulation log (interpolated) or the reference a log recorded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from fpr.model.errors import SceneError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.views.scene.geometry import (
    _HINGE_COLOR,
    _axle_matrix,
    _Group,
    _is_hinge,
    _meshcat,
    _translation,
    _visual_model,
)
from fpr.views.scene.page import SceneView, _Lowered, _Recorder

# colours (0xRRGGBB) of what the scene draws besides the robot's own materials
_GHOST_COLOR, _GHOST_OPACITY = 0x3B8FE0, 0.3
_PLANNED_COLOR = 0x1F5FBF
_TRACKED_COLOR = 0xE07B00
_THRUST_COLOR = 0xD62728
_WAY_COLOR = 0x2CA02C
_VIA_COLOR = 0x9467BD
_GROUND_COLOR = 0xC8D2C0

_CAMERA_FOV = 75.0  # meshcat's camera [deg, vertical]
_CAMERA_ASPECT = 4.0 / 3.0  # the framing holds in pages at least this wide


# ------------------------------------------------------------------------------------------ motions
@dataclass
class _Motion:
    """A motion at the frame times: q (N, n) thesis coordinates, thrust (N, n_d) [N] or None."""

    q: np.ndarray
    thrust: np.ndarray | None


@dataclass
class _Poses:
    """World placements at N configurations."""

    joints: np.ndarray  # (N, n_j, 4, 4): joints carrying visuals or hinges, in _Scene.joint_ids order
    drones: np.ndarray  # (N, n_d, 4, 4): drone centres of mass
    end_effector: np.ndarray  # (N, 3)
    task_point: np.ndarray  # (N, 3): the mission's point (FPR: end-effector; prototype: drone joint)


def _default_configuration(robot) -> np.ndarray:
    """What :func:`fpr.views.scene.view` shows with nothing given: the kind's ``reference_chain``, drones level."""
    return robot.configuration(**dict(zip(robot.layout.chain, robot.kind.reference_chain, strict=True)))


def _frame_times(duration: float, fps: float) -> np.ndarray:
    """k / fps for k = 0, 1, ..., then the duration itself (the animation's real time base) [s]."""
    t = np.arange(int(math.floor(duration * fps * (1.0 + 1e-12))) + 1) / fps
    if duration - t[-1] > 1e-9 * max(duration, 1.0):
        t = np.append(t, duration)
    t[-1] = duration
    return t


def _planned_motion(robot, plan, times: np.ndarray) -> _Motion:
    """The plan at ``times``, at rest on its last point after its end: full q and thrusts."""
    motion = plan.trajectory.evaluate_held(times, order=MOTION_ORDER)  # 6: singularity crossing
    inputs = inverse_dynamics(robot, motion)
    return _Motion(inputs.full_state(robot)[0], inputs.thrust)


def _interpolate(t_from, values, t_to) -> np.ndarray:
    """``values`` (a row per time of ``t_from``) interpolated linearly at ``t_to``, shape (len(t_to), -1)."""
    values = np.asarray(values, dtype=float).reshape(len(t_from), -1)
    return np.stack([np.interp(t_to, t_from, v) for v in values.T], axis=1)


def _tracked_motion(log, times: np.ndarray) -> _Motion:
    """The simulated state and the controller's thrusts at ``times`` (linear interpolation)."""
    return _Motion(_interpolate(log.t, log.q, times), _interpolate(log.t, log.thrust, times))


def _logged_reference(robot, log, times: np.ndarray) -> _Motion:
    """The plan as the log recorded it (chain coordinates and the drones' attitude coordinates); no thrusts."""
    q = np.zeros((len(log.t), robot.nq))
    q[:, robot.indices(robot.layout.chain)] = log.reference[0]
    q[:, robot.indices(robot.layout.rolls)] = log.planned_attitude
    return _Motion(_interpolate(log.t, q, times), None)


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
        # the carried body's path: the 'end_effector' link's, or the kind's task frame's (the spatial FPR's platform)
        main = "end_effector" if model.existFrame("end_effector") else robot.kind.task_frame
        self.end_effector_name = main
        self.end_effector_frame = model.getFrameId(main)
        if self.end_effector_frame >= model.nframes:
            raise SceneError("robot", f"the {robot.name} URDF has no 'end_effector' link: name the link "
                                      "that carries the end-effector (or the task point) 'end_effector'")
        self.task_frame = model.getFrameId(robot.kind.task_frame)
        if self.task_frame >= model.nframes:
            raise SceneError("robot", f"the {robot.name} model has no frame {robot.kind.task_frame!r}, its kind's "
                                      "task_frame: name the frame (link or joint) of the mission's task point")
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
            task[k] = data.oMf[self.task_frame].translation
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
                group.cylinder("hinge", length, radius, _HINGE_COLOR, _axle_matrix(model, j))
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
        """Lines through the end-effector's (or the task frame's) and the drones' centres' positions."""
        mg = self.mg
        lines = {self.end_effector_name: poses.end_effector}
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
        where = self.robot.kind.task_point_labels[0]
        via = "; purple cubes: via points" if (~is_way).any() else ""
        return f"green spheres: way points ({where}){via}"

    def environment(self, shown: list[tuple[_Poses, _Motion | None]]) -> None:
        """The ground plane z = -L (meshcat's grid, at z = 0, hidden), the background, the camera."""
        mg = self.mg
        points = np.concatenate([_visible_points(p, m, self.thrust_scale) for p, m in shown])
        ground = self.robot.kind.ground_height
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


