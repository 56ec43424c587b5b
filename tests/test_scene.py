"""Tests of fpr.views.scene: what the meshcat scene holds, where it puts the bodies, and how a browser shows it.

The unit tests read the recorded meshcat commands (SceneView.object / transform / track) and compare
them with the robot's kinematics (Robot.drone_positions, hinge_positions, frame_placements) and the
plan's inverse dynamics. The browser tests open the written page from a file in headless Chromium
and check the picture (the robot where the camera model puts it), the DOM (meshcat's canvas) and
Chromium's network log (no request from the page).
"""

from __future__ import annotations

import dataclasses
import html
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fpr
import fpr.cli.plan
from fpr.model.errors import FprError, SceneError, ShapeError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.sim.closed_loop import SimulationLog
from fpr.views import scene as scene_module
from fpr.views.scene import THRUST_SCALE, SceneView, view, write_scene
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.trajectory.polynomial import PiecewisePolynomial

FPS = 30.0


# ------------------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def square():
    """The square mission, stop at every way point, with one via point in the middle of each travel."""
    result = plan(load_mission("square"), "none")
    knots = result.trajectory.knots
    times = np.sort(np.concatenate([knots, (knots[:-1] + knots[1:]) / 2]))
    points = np.moveaxis(result.trajectory.evaluate(times, order=4), 0, 1)  # (m+1, 5, n)
    return dataclasses.replace(result, trajectory=PiecewisePolynomial(points, np.diff(times)),
                               is_way=np.isin(times, knots))


@pytest.fixture(scope="module")
def square_scene(square):
    return view(square.robot, square, fps=FPS)


def _planned_q(plan_result, t):
    """Full-model configurations, thrusts, motion and rolls of the plan at times t, at rest after its end."""
    robot = plan_result.robot
    total = plan_result.trajectory.total_duration
    motion = plan_result.trajectory.evaluate(np.minimum(t, total), order=MOTION_ORDER)
    motion[1:, t > total] = 0.0
    inputs = inverse_dynamics(robot, motion)
    return inputs.full_state(robot)[0], inputs.thrust, motion, inputs.roll


def _synthetic_log(plan_result, hold=0.5, rate=150.0):
    """A SimulationLog that tracks the plan with a known error (y off by 5 cm sin t, rolls by 0.02 rad)."""
    robot = plan_result.robot
    t = np.arange(int(round((plan_result.trajectory.total_duration + hold) * rate)) + 1) / rate
    q, thrust, motion, roll = _planned_q(plan_result, t)
    q = q.copy()
    q[:, robot.index["y"]] += 0.05 * np.sin(t)
    q[:, robot.indices(robot.layout.rolls)] += 0.02
    n, n_d = len(t), robot.n_drones
    speeds = np.zeros((n, n_d, 4))
    return SimulationLog(robot.name, tuple(robot.layout.coordinates), tuple(robot.layout.chain), t, q,
                         np.zeros_like(q), motion[:3], roll, roll, speeds, speeds, 1.1 * thrust,
                         np.zeros((n, n_d, 3)), speeds > 0, q[:, :n_d], np.zeros(n), 900.0, 750.0, 1.0)


@pytest.fixture(scope="module")
def square_log(square):
    return _synthetic_log(square)


@pytest.fixture(scope="module")
def simulation_scene(square, square_log):
    return view(square.robot, square, square_log, fps=FPS)


def _children(obj):
    return {c["name"]: c for c in obj["object"]["children"]}


# ------------------------------------------------------------------------------------------ content
def test_plan_scene_holds_the_robot_paths_markers_arrows_and_animation(square_scene, square):
    paths = set(square_scene.paths)
    robot = [f"/meshcat/robot/{j}" for j in ("end_effector_root", "drone_1_hinge", "q21", "drone_2_hinge")]
    arrows = [f"/meshcat/robot/thrust/drone_{i}/{part}" for i in (1, 2) for part in ("shaft", "head")]
    lines = [f"/meshcat/paths/planned/{p}" for p in ("end_effector", "drone_1", "drone_2")]
    way = [f"/meshcat/markers/way_points/{i}" for i in range(5)]
    via = [f"/meshcat/markers/via_points/{i}" for i in range(4)]
    assert set(robot + arrows + lines + way + via + ["/meshcat/ground"]) <= paths
    assert not any(p.startswith("/meshcat/ghost") or p.startswith("/meshcat/paths/tracked") for p in paths)
    assert "/meshcat/markers/way_points/5" not in paths and "/meshcat/markers/via_points/4" not in paths

    # the drones: the example-robot-data body (Collada, with its materials), four propellers, the strut
    drone = _children(square_scene.object("robot/drone_1_hinge"))
    assert drone["drone_1_0"]["type"] == "_meshfile_object" and "<COLLADA" in drone["drone_1_0"]["data"]
    assert {f"drone_1_rotor_{m}_0" for m in range(1, 5)} <= set(drone) and "hinge" in drone
    geometries = {g["uuid"]: g for g in square_scene.object("robot/drone_1_hinge")["geometries"]}
    prop = geometries[drone["drone_1_rotor_1_0"]["geometry"]]
    assert prop["type"] == "BufferGeometry"
    assert len(prop["data"]["attributes"]["position"]["array"].data) > 10_000  # thousands of vertices
    # the chain: rods, end-effector, hinge axles on q21 and on the drone joints
    assert {"link_1_0", "end_effector_0"} <= set(_children(square_scene.object("robot/end_effector_root")))
    assert {"link_2_0", "hinge"} <= set(_children(square_scene.object("robot/q21")))
    # the ground is at z = -L, under the whole scene
    ground = square_scene.transform("ground")
    size = square_scene.object("ground")["geometries"][0]
    top = ground[2, 3] + size["depth"] / 2
    assert top == pytest.approx(-square.robot.link_length, abs=2e-3)

    # animation on the real time base: 30 key frames per second, from 0 to the plan's duration
    t, values = square_scene.track("robot/drone_1_hinge", "position")
    assert square_scene.duration == pytest.approx(square.trajectory.total_duration) == 12.0
    assert t[0] == 0.0 and t[-1] == pytest.approx(12.0, abs=1e-12) and len(t) == 12 * FPS + 1
    np.testing.assert_allclose(np.diff(t), 1 / FPS, atol=1e-12)
    animation = [c for c in square_scene.commands if c["type"] == "set_animation"]
    assert len(animation) == 1 and animation[0]["options"]["play"]


def test_bodies_are_placed_by_the_kinematics(square_scene, square):
    robot = square.robot
    t, position = square_scene.track("robot/thrust/drone_2", "position")
    _, quaternion = square_scene.track("robot/thrust/drone_2", "quaternion")
    _, hinge = square_scene.track("robot/drone_1_hinge", "position")
    sampled = square.sampled(FPS)  # the plan on the same time base
    np.testing.assert_allclose(t, sampled.t, atol=1e-12)
    q = sampled.inputs.full_state(robot)[0]
    for k in (0, 47, 200, len(t) - 1):
        np.testing.assert_allclose(position[k], robot.drone_positions(q[k])[1], atol=1e-12)
        np.testing.assert_allclose(hinge[k], robot.hinge_positions(q[k])[0], atol=1e-12)
        x, y, z, w = quaternion[k]
        rotation = robot.frame_placements(q[k])[1].rotation
        expected = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                             [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                             [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(rotation, expected, atol=1e-9)
    # the static transforms are the first key frame
    np.testing.assert_allclose(square_scene.transform("robot/thrust/drone_2")[:3, 3], position[0], atol=1e-12)
    # the end-effector path goes through p = (x, y, z) of q
    line = square_scene.object("paths/planned/end_effector")["geometries"][0]
    vertices = np.frombuffer(line["data"]["attributes"]["position"]["array"].data, np.float32).reshape(-1, 3)
    np.testing.assert_allclose(vertices, q[:, :3], atol=1e-6)


def test_way_and_via_points_are_marked_at_the_end_effector(square_scene, square):
    points = square.trajectory.points[:, 0, :2]  # (y, z) of s at every knot
    for kind, flags in (("way_points", square.is_way), ("via_points", ~square.is_way)):
        for n, (y, z) in enumerate(points[flags]):
            marker = square_scene.transform(f"markers/{kind}/{n}")
            np.testing.assert_allclose(marker[:3, 3], [0.0, y, z], atol=1e-12)
    assert square_scene.object("markers/way_points/0")["geometries"][0]["type"] == "SphereGeometry"
    assert square_scene.object("markers/via_points/0")["geometries"][0]["type"] == "BoxGeometry"


def test_thrust_arrows_are_proportional_to_the_thrust(square_scene, square):
    t, scale = square_scene.track("robot/thrust/drone_1/shaft", "scale")
    _, head = square_scene.track("robot/thrust/drone_1/head", "position")
    thrust = square.sampled(FPS).inputs.thrust
    assert thrust[:, 0].min() > 5.0  # a drone never stops pushing in this motion
    np.testing.assert_allclose(scale[:, 2], THRUST_SCALE * thrust[:, 0], rtol=1e-12)
    np.testing.assert_allclose(scale[:, :2], 1.0)
    np.testing.assert_allclose(head[:, 2], scale[:, 2], rtol=1e-12)
    np.testing.assert_allclose(head[:, :2], 0.0)
    assert np.ptp(scale[:, 2]) > 0.01  # the arrows do change along the motion
    doubled = view(square.robot, square, fps=5.0, thrust_scale=2 * THRUST_SCALE)
    t5, scale5 = doubled.track("robot/thrust/drone_1/shaft", "scale")
    np.testing.assert_allclose(scale5[:, 2], 2 * THRUST_SCALE * _planned_q(square, t5)[1][:, 0], rtol=1e-12)


def test_simulation_scene_shows_the_tracked_robot_and_the_plan_as_a_ghost(simulation_scene, square,
                                                                          square_log):
    robot = square.robot
    paths = set(simulation_scene.paths)
    assert {"/meshcat/ghost/drone_1_hinge", "/meshcat/ghost/thrust/drone_1", "/meshcat/paths/tracked/drone_2",
            "/meshcat/paths/tracked/end_effector", "/meshcat/paths/planned/drone_2"} <= paths
    assert simulation_scene.duration == pytest.approx(square_log.t[-1]) == pytest.approx(12.5)
    # the solid robot follows the log, the ghost the plan (held at its end)
    t, solid = simulation_scene.track("robot/thrust/drone_1", "position")
    _, ghost = simulation_scene.track("ghost/thrust/drone_1", "position")
    assert t[-1] == pytest.approx(12.5)
    q_plan, _, _, _ = _planned_q(square, t)
    for k in (0, 100, len(t) - 1):
        q_log = square_log.q[np.argmin(np.abs(square_log.t - t[k]))]  # the log's times hold every frame time
        np.testing.assert_allclose(solid[k], robot.drone_positions(q_log)[0], atol=1e-9)
        np.testing.assert_allclose(ghost[k], robot.drone_positions(q_plan[k])[0], atol=1e-9)
    assert np.abs(solid - ghost).max() > 0.04  # the known tracking error shows
    # the solid arrows show the logged (controller's) thrust, the ghost's the plan's
    _, scale = simulation_scene.track("robot/thrust/drone_2/shaft", "scale")
    _, ghost_scale = simulation_scene.track("ghost/thrust/drone_2/shaft", "scale")
    np.testing.assert_allclose(scale[:, 2], 1.1 * ghost_scale[:, 2], rtol=1e-9)
    # the ghost is translucent, every one of its materials
    for path in ("ghost/drone_1_hinge", "ghost/end_effector_root"):
        materials = simulation_scene.object(path)["materials"]
        assert materials and all(m["transparent"] and m["opacity"] < 0.5 for m in materials)
    assert all(not m["transparent"] for m in simulation_scene.object("robot/q21")["materials"])


def test_a_log_alone_gets_its_ghost_from_the_recorded_reference(square, square_log):
    robot = square.robot
    scene = view(robot, log=square_log, fps=5.0)
    t, ghost = scene.track("ghost/drone_2_hinge", "position")
    q_plan, _, _, _ = _planned_q(square, t)
    for k in (0, 20, len(t) - 1):
        np.testing.assert_allclose(ghost[k], robot.hinge_positions(q_plan[k])[1], atol=1e-9)
    assert "/meshcat/ghost/thrust/drone_1" not in scene.paths  # the log has no planned thrust
    assert not any("markers" in p for p in scene.paths)  # nor way points


def test_a_configuration_shows_a_still_robot():
    robot = fpr.load("fpr")
    q = robot.configuration(y=0.3, z=0.2, phi=4.0, q21=1.4, phi1=0.1, phi2=-0.2)
    still = view(robot, configuration=q)
    assert still.duration is None and not any(c["type"] == "set_animation" for c in still.commands)
    assert not any("thrust" in p or "paths" in p for p in still.paths)
    placement = robot.frame_placements(q)[0]
    hinge = still.transform("robot/drone_1_hinge")
    np.testing.assert_allclose(hinge[:3, 3], robot.hinge_positions(q)[0], atol=1e-12)
    # the drone's centre, d above its hinge along the drone's body z, in the same node
    np.testing.assert_allclose(hinge[:3, :3], placement.rotation, atol=1e-12)
    np.testing.assert_allclose(hinge[:3, 3] + robot.hinge_offset * hinge[:3, 2], placement.translation,
                               atol=1e-12)

    proto = fpr.load("prototype")
    prototype = view(proto)  # default: the kind's reference chain, arm down
    base = _children(prototype.object("robot/base"))
    assert {"base_0", "base_1"} <= set(base)  # the fixed pivot and its post
    assert {"/meshcat/robot/q1", "/meshcat/robot/q2", "/meshcat/robot/drone_1_hinge"} <= set(prototype.paths)
    q1, q2 = proto.kind.reference_chain
    length = proto.link_length  # drone joint L u(q1) + L u(q1 + q2), by hand (x = 0: the plane y, z)
    np.testing.assert_allclose(prototype.transform("robot/drone_1_hinge")[:3, 3],
                               [0.0, length * (np.cos(q1) + np.cos(q1 + q2)), length * (np.sin(q1) + np.sin(q1 + q2))],
                               atol=1e-12)


def test_prototype_way_points_are_the_drone_joint():
    result = plan(load_mission("prototype-tour").replace(times=[1.0] * 7), "none")
    scene = view(result.robot, result, fps=2.0)
    way = load_mission("prototype-tour").way_points  # task space: the drone joint (y, z)
    for n, (y, z) in enumerate(way):
        np.testing.assert_allclose(scene.transform(f"markers/way_points/{n}")[:3, 3], [0.0, y, z], atol=1e-9)


def test_a_motion_through_the_singularity_is_drawn():
    result = plan(load_mission("cross-singularity"), "none")  # prototype: one assembly mode to the other
    scene = view(result.robot, result, fps=5.0)
    t, scale = scene.track("robot/thrust/drone_1/shaft", "scale")
    q = _planned_q(result, t)[0]
    q2 = q[:, result.robot.index["q2"]]
    assert q2.min() < 0 < q2.max()  # q2 = 0 on the way: the thrust there needs xi up to its 6th derivative
    assert np.all(np.isfinite(scale)) and scene.duration == pytest.approx(result.trajectory.total_duration)


@pytest.mark.parametrize("case, error, match", [
    ("not a robot", SceneError, "robot"),
    ("configuration shape", ShapeError, r"configuration.shape=\(3,\)"),
    ("configuration not finite", SceneError, "not finite"),
    ("configuration with a plan", SceneError, "standing still"),
    ("fps", SceneError, "fps"),
    ("thrust scale", SceneError, "thrust_scale"),
    ("plan of another robot", SceneError, "another robot"),
    ("not a plan", SceneError, "PlanResult"),
    ("log of another robot", SceneError, "simulation of the 'prototype'"),
    ("log not increasing", SceneError, "increasing"),
])
def test_bad_inputs_raise(case, error, match, square, square_log):
    robot, replace = square.robot, dataclasses.replace
    calls = {
        "not a robot": lambda: view("fpr"),
        "configuration shape": lambda: view(robot, configuration=[0.0, 1.0, 2.0]),
        "configuration not finite": lambda: view(robot, configuration=np.full(robot.nq, np.nan)),
        "configuration with a plan": lambda: view(robot, square, configuration=np.zeros(robot.nq)),
        "fps": lambda: view(robot, square, fps=0.0),
        "thrust scale": lambda: view(robot, square, thrust_scale=float("nan")),
        "plan of another robot": lambda: view(fpr.load("fpr", link_length=1.0), square),
        "not a plan": lambda: view(robot, square.trajectory),
        "log of another robot": lambda: view(robot, log=replace(square_log, robot_name="prototype")),
        "log not increasing": lambda: view(robot, log=replace(square_log, t=square_log.t[::-1])),
    }
    with pytest.raises(error, match=match) as info:
        calls[case]()
    assert isinstance(info.value, FprError)


def test_meshcat_missing_gives_the_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "meshcat", None)
    with pytest.raises(ImportError, match="pip install meshcat"):
        view(fpr.load("fpr"))


# ------------------------------------------------------------------------------------------ the page
def test_page_is_standalone(square_scene, tmp_path):
    page = square_scene.html
    assert page.startswith("<!DOCTYPE html>") and "MeshCat.Viewer" in page
    assert "default-src 'none'" in page  # the browser refuses any load the page would try
    markup = re.sub(r"<script>.*?</script>", "", page, flags=re.S)
    assert not re.search(r"(src|href)\s*=", markup) and "http" not in markup.replace("http-equiv", "")
    # inside the scripts, the only URLs are XML namespace names (strings, never loaded)
    assert set(re.findall(r"https?://[^\s\"'`)]+", page)) <= {"http://www.w3.org/1999/xhtml"}
    assert not re.search(r"\bimport\s*\(|new\s+WebSocket\s*\(\s*[\"']", page)
    written = square_scene.write(tmp_path)
    assert written == tmp_path / "scene.html" and written.read_text(encoding="utf-8") == page
    assert write_scene(tmp_path / "other.html", fpr.load("fpr")).is_file()
    inline = square_scene._repr_html_()
    assert inline.startswith("<iframe srcdoc=\"") and html.unescape(inline.split('"')[1]) == page


def test_cli_writes_the_scene_and_serves_it(tmp_path, monkeypatch, capsys):
    served = []

    class FakeVisualizer:
        def url(self):
            return "http://127.0.0.1:7000/static/"

    def fake_serve(self, zmq_url=None):
        served.append(self)
        return FakeVisualizer()

    def interrupt(_):
        raise KeyboardInterrupt

    monkeypatch.setattr(SceneView, "serve", fake_serve)
    monkeypatch.setattr(fpr.cli.plan.time, "sleep", interrupt)
    out = tmp_path / "served"
    code = fpr.cli.plan.main(["--method", "none", "--rate", "20", "--no-plots", "--quiet",
                          "--serve", "--out", str(out)])
    assert code == 0 and len(served) == 1 and served[0].duration == pytest.approx(12.0)
    assert "meshcat: open http://127.0.0.1:7000/static/" in capsys.readouterr().out
    assert "MeshCat.Viewer" in (out / "scene.html").read_text(encoding="utf-8")

    out = tmp_path / "written"
    code = fpr.cli.plan.main(["--method", "none", "--rate", "20", "--no-plots", "--quiet",
                          "--meshcat", "--out", str(out)])
    assert code == 0 and (out / "scene.html").is_file() and len(served) == 1


def test_serve_sends_the_scene_to_a_live_server():
    import urllib.request

    visualizer = scene_module.serve(fpr.load("prototype"))
    try:
        assert re.match(r"http://127\.0\.0\.1:\d+/static/", visualizer.url())
        with urllib.request.urlopen(visualizer.url(), timeout=10) as response:
            assert b"main.min.js" in response.read()
        assert "embedded-json" in visualizer.static_html()  # the server holds the scene: it renders it back
    finally:
        process = visualizer.window.server_proc
        process.kill()
        process.wait(timeout=10)


# ------------------------------------------------------------------------------------------ in a browser
def _find_chromium():
    for candidate in (os.environ.get("FPR_CHROMIUM"), "/usr/bin/chromium", shutil.which("chromium"),
                      shutil.which("chromium-browser"), shutil.which("google-chrome")):
        if candidate and Path(candidate).is_file():
            return candidate
    return None


@pytest.fixture(scope="session")
def chromium():
    """A Chromium executable, or the test skips (it installs nothing: .ci/run installs Debian's chromium)."""
    found = _find_chromium()
    if found is None:
        pytest.skip("no Chromium executable: install Debian's (apt-get install chromium) or set FPR_CHROMIUM "
                    "to one")
    return found


def _browse(chromium, page: Path, tmp_path: Path, *, screenshot: bool) -> tuple[Path, list[dict]]:
    """Open ``page`` (file://); returns the screenshot or the DOM dump, and the page's network requests."""
    name = f"{page.stem}-{'screenshot' if screenshot else 'dom'}"
    output = tmp_path / (f"{name}.png" if screenshot else f"{name}.html")
    net_log = tmp_path / f"{name}.net.json"
    command = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
               "--disable-component-update", "--no-first-run", "--disable-sync", "--disable-quic",
               "--host-resolver-rules=MAP * ~NOTFOUND",  # nothing leaves the machine, whoever asks
               f"--user-data-dir={tmp_path / ('profile-' + name)}", f"--log-net-log={net_log}",
               "--window-size=800,600", "--virtual-time-budget=1000",  # virtual ms: the page loads at once
               f"--screenshot={output}" if screenshot else "--dump-dom", page.resolve().as_uri()]
    run = subprocess.run(command, capture_output=True, timeout=120)
    if not screenshot:
        output.write_bytes(run.stdout)
    assert output.is_file() and output.stat().st_size > 0, run.stderr.decode(errors="replace")[-2000:]
    log = json.loads(net_log.read_text(encoding="utf-8"))
    names = {v: k for k, v in log["constants"]["logEventTypes"].items()}
    # Chromium's own background requests have no origin; anything the page asks for has its (file:) origin
    requests = [e["params"] for e in log["events"] if names[e["type"]] == "URL_REQUEST_START_JOB"
                and "url" in e.get("params", {}) and e["params"].get("initiator") != "not an origin"]
    return output, requests


def _project(points, eye, target, width, height, fov=75.0):
    """Pixel (column, row) of world points through meshcat's perspective camera (z up, vertical fov)."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = np.atleast_2d(points) - eye
    depth, x, y = rel @ forward, rel @ right, rel @ up
    tan = np.tan(np.radians(fov) / 2)
    column = (1 + x / (depth * tan * width / height)) * width / 2
    return np.stack([column, (1 - y / (depth * tan)) * height / 2], axis=1)


def test_a_still_robot_is_drawn_where_the_camera_puts_it(chromium, tmp_path):
    import matplotlib.image

    robot = fpr.load("fpr")
    q = robot.configuration(y=0.2, z=0.1, phi=5 * np.pi / 4, q21=np.pi / 2, phi1=0.2, phi2=-0.2)
    still = view(robot, configuration=q, title="still")
    shot, requests = _browse(chromium, still.write(tmp_path / "still.html"), tmp_path, screenshot=True)
    assert requests == []
    image = matplotlib.image.imread(shot)[..., :3]
    height, width = image.shape[:2]
    eye, target = still.camera
    drones = _project(robot.drone_positions(q), eye, target, width, height)
    end_effector = _project(q[:3], eye, target, width, height)[0]
    assert np.all((drones > 50) & (drones < [width - 50, height - 50]))  # the camera frames the robot
    for column, row in np.round(drones).astype(int):  # the black drone bodies
        patch = image[row - 8:row + 9, column - 8:column + 9]
        assert (patch.max(axis=2) < 0.25).sum() >= 10, (column, row)
    column, row = np.round(end_effector).astype(int)  # the orange end-effector
    patch = image[row - 4:row + 5, column - 4:column + 5].reshape(-1, 3)
    orange = (patch[:, 0] > 0.7) & (patch[:, 1] > 0.3) & (patch[:, 1] < 0.7) & (patch[:, 2] < 0.35)
    assert orange.sum() >= 10
    # the background is plain where nothing is drawn (above the drones' midpoint, between them)
    assert image[:30, width // 2 - 20:width // 2 + 20].min() > 0.85


def test_plan_page_renders_offline_in_a_browser(chromium, tmp_path, square_scene):
    import matplotlib.image

    page = square_scene.write(tmp_path / "scene.html")
    shot, requests = _browse(chromium, page, tmp_path, screenshot=True)
    assert requests == []
    image = matplotlib.image.imread(shot)[..., :3]
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    dark = image.max(axis=2) < 0.25  # drone bodies
    red = (r > 0.6) & (g < 0.3) & (b < 0.3)  # thrust arrows
    blue = (b > 0.55) & (r < 0.35)  # planned paths
    green = (g > 0.45) & (r < 0.35) & (b < 0.35)  # way points
    central = np.zeros_like(dark)
    central[60:, 100:] = True  # away from the legend
    assert (dark & central).sum() > 100 and (red & central).sum() > 100
    assert (blue & central).sum() > 300 and (green & central).sum() > 50
    dom, requests = _browse(chromium, page, tmp_path, screenshot=False)
    assert requests == []
    text = dom.read_text(encoding="utf-8", errors="replace")
    assert re.search(r"<canvas[^>]*width=\"\d+\"", text)  # meshcat's WebGL canvas
    assert "dg main" in text or "Open Controls" in text  # and its control panel


def test_the_same_scene_gives_the_same_bytes(square, square_log):
    """The three.js ids are numbered in the order the objects are made (ours and meshcat's), so that the same
    scene writes the same page; meshcat's own ids are random again afterwards.
    """
    import uuid

    from fpr.views.scene.geometry import _meshcat

    scene = view(square.robot, square, square_log, fps=FPS)
    assert view(square.robot, square, square_log, fps=FPS).html == scene.html
    numbered = re.compile(r"0{8}-0{4}-0{4}-0{4}-[0-9a-f]{12}")
    drone = scene.object("robot/drone_1_hinge")
    assert numbered.fullmatch(drone["object"]["uuid"]) and numbered.fullmatch(drone["geometries"][0]["uuid"])
    assert numbered.fullmatch(scene.object("paths/planned/drone_1")["object"]["uuid"])  # one of meshcat's
    assert _meshcat().geometry.uuid is uuid
