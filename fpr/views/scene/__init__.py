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

meshcat is optional: it is imported by the functions that need it, with an install hint;
``import fpr.views.scene`` works without it.

The package, one concept per module:

================================ =================================================================
:mod:`~fpr.views.scene.api`       :func:`view`, :func:`write_scene`, :func:`serve`, the input checks
:mod:`~fpr.views.scene.builder`   the scene: robot, ghost, thrust arrows, paths, markers, ground,
                                  camera, animation
:mod:`~fpr.views.scene.geometry`  the robot's URDF visuals as three.js groups and materials
:mod:`~fpr.views.scene.page`      :class:`SceneView`, the recorder, the standalone page
================================ =================================================================
"""

from fpr.views.scene.api import DEFAULT_FPS, THRUST_SCALE, serve, view, write_scene
from fpr.views.scene.geometry import EMBEDDED_MESH_LIMIT
from fpr.views.scene.page import ROOT, SceneView

__all__ = ["DEFAULT_FPS", "EMBEDDED_MESH_LIMIT", "ROOT", "SceneView", "THRUST_SCALE", "serve", "view",
           "write_scene"]
