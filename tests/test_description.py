"""Tests of the robot descriptions (urdf/*.xacro, the generated urdf/*.urdf, fpr.model.description)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
import yourdfpy

from fpr.model import description
from fpr.model.errors import RobotDefinitionError, UnknownRobotError

PARAMS = yaml.safe_load((description.URDF_DIR / "parameters.yaml").read_text(encoding="utf-8"))
DRONES = {"fpr": ("drone_1", "drone_2"), "prototype": ("drone_1",), "fpr3": ("drone_1", "drone_2", "drone_3")}
PLANAR = ("fpr", "prototype")  # their links and masses; the spatial FPR's: tests/test_fpr3_model.py
ROTOR_DIRECTIONS = {1: (1, 0), 2: (0, 1), 3: (-1, 0), 4: (0, -1)}  # +x, +y, -x, -y

X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
JOINTS = {
    "fpr": {
        # name: (type, axis, parent, child)
        "link_1_joint": ("fixed", None, "end_effector", "link_1"),
        "q21": ("continuous", X, "end_effector", "link_2"),
        "drone_1_hinge": ("continuous", X, "link_1", "drone_1"),
        "drone_2_hinge": ("continuous", X, "link_2", "drone_2"),
    },
    "prototype": {
        "pivot_yaw": ("continuous", Z, "base", "pivot_yaw_link"),
        "pivot_pitch": ("continuous", Y, "pivot_yaw_link", "pivot_pitch_link"),
        "q1": ("continuous", X, "pivot_pitch_link", "link_1"),
        "q2": ("continuous", X, "link_1", "link_2"),
        "end_effector_joint": ("fixed", None, "link_2", "end_effector"),
        "drone_1_hinge": ("continuous", X, "link_2", "drone_1"),
    },
    "fpr3": {
        **{f"q{i}": ("continuous", Z, "platform", f"leg_{i}") for i in (1, 2, 3)},
        **{f"leg_{i}_tip_joint": ("fixed", None, f"leg_{i}", f"leg_{i}_tip") for i in (1, 2, 3)},
        **{f"drone_{i}_ball_pitch": ("continuous", Y, f"leg_{i}_tip", f"drone_{i}_ball_pitch_link")
           for i in (1, 2, 3)},
        **{f"drone_{i}_ball_yaw": ("continuous", Z, f"drone_{i}_ball_pitch_link", f"drone_{i}_ball_yaw_link")
           for i in (1, 2, 3)},
        **{f"drone_{i}_hinge": ("continuous", X, f"drone_{i}_ball_yaw_link", f"drone_{i}")
           for i in (1, 2, 3)},
    },
}
for _robot, _joints in JOINTS.items():
    for _drone in DRONES[_robot]:
        _joints[f"{_drone}_center_joint"] = ("fixed", None, _drone, f"{_drone}_center")
        for _m in range(1, 5):
            _rotor = f"{_drone}_rotor_{_m}"
            _joints[f"{_rotor}_joint"] = ("fixed", None, f"{_drone}_center", _rotor)


def _package_handler(fname: str) -> str:
    """Resolve package:// URIs for yourdfpy with fpr.model.description.mesh_package_dirs()."""
    prefix = "package://"
    if fname.startswith(prefix):
        for folder in description.mesh_package_dirs():
            candidate = Path(folder) / fname[len(prefix) :]
            if candidate.exists():
                return str(candidate)
    return fname


def _load_yourdfpy(robot: str, **kwargs) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(str(description.urdf_path(robot)), **kwargs)


def _load_pinocchio(robot: str, path: str | Path | None = None) -> pin.Model:
    path = Path(path or description.urdf_path(robot))
    return _load_pinocchio_from_text(robot, path.read_text(encoding="utf-8"))


def _load_pinocchio_from_text(robot: str, text: str) -> pin.Model:
    # the continuous hinges read with one angle each, as fpr.model.robot.Robot does
    text = description.single_angle_urdf(text)
    if robot in ("fpr", "fpr3"):  # floating: the root joint is added at load
        return pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
    return pin.buildModelFromXML(text)


def _origin_xyz(urdf_text: str, joint: str) -> np.ndarray:
    element = ET.fromstring(urdf_text).find(f"joint[@name='{joint}']/origin")
    return np.array([float(v) for v in element.get("xyz").split()])


# --- generation -----------------------------------------------------------------------------------


@pytest.mark.parametrize("robot", description.DESCRIPTIONS)
def test_committed_urdf_matches_xacro(robot, tmp_path, monkeypatch):
    # from another working directory: relative paths in the xacro files must not depend on it
    monkeypatch.chdir(tmp_path)
    assert description.generate_urdf(robot) == description.urdf_path(robot).read_text(encoding="utf-8"), (
        f"urdf/{description.urdf_path(robot).name} is stale: run python -m fpr.model.description"
    )


def test_check_command_passes():
    assert description.main(["--check"]) == 0


def test_paths_and_unknown_robot():
    assert description.DESCRIPTIONS == ("fpr", "fpr3", "prototype")
    assert description.xacro_path("fpr").name == "fpr.urdf.xacro"
    assert description.urdf_path("prototype") == description.URDF_DIR / "prototype.urdf"
    for function in (description.xacro_path, description.urdf_path, description.generate_urdf):
        with pytest.raises(UnknownRobotError, match="'fpr', 'fpr3', 'prototype'"):
            function("tripod")
    with pytest.raises(RobotDefinitionError, match="no such xacro file"):
        description.xacro_path("/nowhere/tripod.urdf.xacro")


def test_a_xacro_path_is_a_description(tmp_path):
    """A robot outside the library names its xacro file by path: same text as by name, URDF beside it."""
    path = description.xacro_path("prototype")
    assert description.generate_urdf(path) == description.generate_urdf("prototype")
    copy = tmp_path / "copy.urdf.xacro"
    copy.write_text(path.read_text(encoding="utf-8").replace(
        '<xacro:include filename="', f'<xacro:include filename="{description.URDF_DIR.as_posix()}/'), encoding="utf-8")
    assert description.urdf_path(copy) == tmp_path / "copy.urdf"
    assert description.main([str(copy)]) == 0
    text = (tmp_path / "copy.urdf").read_text(encoding="utf-8")
    assert f"Generated from {copy.as_posix()} and" in text
    assert text.split("-->", 1)[1] == description.generate_urdf("prototype").split("-->", 1)[1]


def test_xacro_arguments_are_parameter_keys():
    names = description.xacro_arguments()
    assert {"link_length", "drone_mass", "hinge_offset", "rotor_arm"} <= set(names)
    assert set(names) <= set(PARAMS)
    with pytest.raises(ValueError, match="link_lenght"):
        description.generate_urdf("fpr", link_lenght=1.0)


def test_mesh_uris_are_machine_independent():
    dirs = description.mesh_package_dirs()
    for robot in description.DESCRIPTIONS:
        meshes = ET.fromstring(description.urdf_path(robot).read_text(encoding="utf-8")).iter("mesh")
        for mesh in meshes:
            uri = mesh.get("filename")
            assert uri.startswith("package://example-robot-data/robots/"), uri
            if dirs:
                assert any((Path(d) / uri[len("package://") :]).is_file() for d in dirs), uri


def test_mesh_package_dirs():
    dirs = description.mesh_package_dirs()
    assert isinstance(dirs, list)
    for folder in dirs:
        assert (Path(folder) / "example-robot-data" / "robots" / "hector_description").is_dir()


@pytest.mark.parametrize("robot", PLANAR)
def test_xacro_arg_overrides_link_length(robot):
    text = description.generate_urdf(robot, link_length=1.0)
    sign = -1.0 if robot == "fpr" else 1.0
    hinges = [f"{drone}_hinge" for drone in DRONES[robot]] + (["q2"] if robot == "prototype" else [])
    for joint in hinges:
        np.testing.assert_allclose(_origin_xyz(text, joint), [0.0, sign * 1.0, 0.0])
    model = _load_pinocchio_from_text(robot, text)
    link = model.inertias[model.getJointId("q21" if robot == "fpr" else "q1")]
    np.testing.assert_allclose(link.lever, [0.0, sign * 0.5, 0.0])
    # the default is untouched
    for joint in hinges:
        np.testing.assert_allclose(
            _origin_xyz(description.generate_urdf(robot), joint), [0.0, sign * PARAMS["link_length"], 0.0]
        )


def test_write_urdf(tmp_path):
    path = description.write_urdf("prototype", tmp_path / "p.urdf", drone_mass=2.0)
    model = _load_pinocchio("prototype", path)
    expected = 2.0 + 2 * PARAMS["link_mass"] + PARAMS["end_effector_mass"] + 2 * PARAMS["pivot_mass"]
    assert pin.computeTotalMass(model) == pytest.approx(expected, rel=1e-12)


# --- the URDF as read by yourdfpy ---------------------------------------------------------------


@pytest.mark.parametrize("robot", description.DESCRIPTIONS)
def test_yourdfpy_loads(robot):
    urdf = _load_yourdfpy(robot, load_meshes=False, build_scene_graph=True)
    assert urdf.validate()
    assert urdf.base_link == {"fpr": "end_effector", "prototype": "base", "fpr3": "platform"}[robot]
    assert urdf.robot.name == {"fpr": "fpr", "prototype": "fpr_prototype", "fpr3": "fpr3"}[robot]


@pytest.mark.skipif(not description.mesh_package_dirs(), reason="example-robot-data is not installed")
@pytest.mark.parametrize("robot", description.DESCRIPTIONS)
def test_yourdfpy_loads_meshes(robot):
    urdf = _load_yourdfpy(robot, filename_handler=_package_handler)
    names = set(urdf.scene.geometry)
    for drone in DRONES[robot]:
        assert any(name.startswith(f"{drone}_body") for name in names)
        assert f"{drone}_rotor_1_propeller" in names


@pytest.mark.parametrize("robot", description.DESCRIPTIONS)
def test_inertials_are_physical(robot):
    urdf = _load_yourdfpy(robot, load_meshes=False)
    with_inertial = [link for link in urdf.robot.links if link.inertial is not None]
    assert with_inertial
    for link in with_inertial:
        assert link.inertial.mass > 0, link.name
        inertia = np.asarray(link.inertial.inertia)
        np.testing.assert_allclose(inertia, inertia.T)
        assert np.all(np.linalg.eigvalsh(inertia) > 0), link.name
        a, b, c = np.diag(inertia)
        assert a + b >= c and b + c >= a and c + a >= b, link.name
    # massless frames carry no inertial
    names = {link.name for link in with_inertial}
    for drone in DRONES[robot]:
        assert f"{drone}_center" not in names
        assert not any(f"{drone}_rotor_{m}" in names for m in range(1, 5))


@pytest.mark.parametrize("robot", PLANAR)
def test_inertial_values_follow_parameters(robot):
    urdf = _load_yourdfpy(robot, load_meshes=False)
    links = urdf.link_map
    for drone in DRONES[robot]:
        inertial = links[drone].inertial
        assert inertial.mass == pytest.approx(PARAMS["drone_mass"])
        np.testing.assert_allclose(inertial.origin[:3, 3], [0, 0, PARAMS["hinge_offset"]])
        np.testing.assert_allclose(
            np.diag(inertial.inertia), [PARAMS["drone_ixx"], PARAMS["drone_iyy"], PARAMS["drone_izz"]]
        )
    m, r, length = PARAMS["link_mass"], PARAMS["link_radius"], PARAMS["link_length"]
    sign = -1 if robot == "fpr" else 1
    for name in ("link_1", "link_2"):
        inertial = links[name].inertial
        assert inertial.mass == pytest.approx(m)
        np.testing.assert_allclose(inertial.origin[:3, 3], [0, sign * length / 2, 0])
        transverse = m * (3 * r**2 + length**2) / 12
        np.testing.assert_allclose(np.diag(inertial.inertia), [transverse, m * r**2 / 2, transverse])
    inertial = links["end_effector"].inertial
    m, r = PARAMS["end_effector_mass"], PARAMS["end_effector_radius"]
    assert inertial.mass == pytest.approx(m)
    np.testing.assert_allclose(inertial.inertia, 0.4 * m * r**2 * np.eye(3))


@pytest.mark.parametrize("robot", description.DESCRIPTIONS)
def test_joint_types_and_axes(robot):
    urdf = _load_yourdfpy(robot, load_meshes=False)
    joints = urdf.joint_map
    assert set(joints) == set(JOINTS[robot])
    for name, (kind, axis, parent, child) in JOINTS[robot].items():
        joint = joints[name]
        assert joint.type == kind, name
        assert (joint.parent, joint.child) == (parent, child), name
        if kind == "continuous":  # a passive hinge: no angle limit for any reader to enforce
            np.testing.assert_allclose(joint.axis, axis, err_msg=name)
            assert joint.limit is None or (joint.limit.lower is None and joint.limit.upper is None), name


# --- the URDF as read by Pinocchio --------------------------------------------------------------


@pytest.mark.parametrize("robot", PLANAR)
def test_pinocchio_loads_with_total_mass(robot):
    model = _load_pinocchio(robot)
    drones = len(DRONES[robot])
    expected = drones * PARAMS["drone_mass"] + 2 * PARAMS["link_mass"] + PARAMS["end_effector_mass"]
    if robot == "prototype":  # the pivot's two bearing rings, on the fixed point
        expected += 2 * PARAMS["pivot_mass"]
    assert pin.computeTotalMass(model) == pytest.approx(expected, rel=1e-12)
    if robot == "fpr":
        assert (model.nq, model.nv) == (7 + 3, 6 + 3)
        assert list(model.names)[1:] == ["root_joint", "drone_1_hinge", "q21", "drone_2_hinge"]
    else:
        assert (model.nq, model.nv) == (5, 5)
        assert list(model.names)[1:] == ["pivot_yaw", "pivot_pitch", "q1", "q2", "drone_1_hinge"]


@pytest.mark.skipif(not description.mesh_package_dirs(), reason="example-robot-data is not installed")
@pytest.mark.parametrize("robot", description.DESCRIPTIONS)
def test_pinocchio_loads_meshes(robot):
    model = _load_pinocchio(robot)
    geometry = pin.buildGeomFromUrdf(
        model,
        str(description.urdf_path(robot)),
        pin.GeometryType.VISUAL,
        package_dirs=description.mesh_package_dirs(),
    )
    paths = [g.meshPath for g in geometry.geometryObjects if g.meshPath.endswith(".dae")]
    assert paths and all(Path(p).is_file() for p in paths)


def _random_configuration(model: pin.Model, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = pin.neutral(model)
    for joint in model.joints[1:]:
        if joint.nq == 1:
            q[joint.idx_q] = rng.uniform(-np.pi, np.pi)
    if model.names[1] == "root_joint":
        q[:3] = rng.normal(size=3)
        q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, size=3))).coeffs()
    return q


@pytest.mark.parametrize("robot", description.DESCRIPTIONS)
def test_rotor_frames(robot):
    model = _load_pinocchio(robot)
    data = model.createData()
    q = _random_configuration(model)
    pin.framesForwardKinematics(model, data, q)
    arm = PARAMS["rotor_arm"]
    offset = PARAMS["ball_offset" if robot == "fpr3" else "hinge_offset"]  # the spatial FPR's: on balls
    for drone in DRONES[robot]:
        center = data.oMf[model.getFrameId(f"{drone}_center")]
        hinge = data.oMf[model.getFrameId(drone)]
        # the centre is hinge_offset above the hinge along body z, with the body's orientation
        np.testing.assert_allclose(
            center.actInv(hinge.translation), [0, 0, -offset], atol=1e-12
        )
        np.testing.assert_allclose(center.rotation, hinge.rotation, atol=1e-12)
        for m, (dx, dy) in ROTOR_DIRECTIONS.items():
            rotor = data.oMf[model.getFrameId(f"{drone}_rotor_{m}")]
            local = center.actInv(rotor.translation)
            assert np.linalg.norm(rotor.translation - center.translation) == pytest.approx(arm)
            assert local[2] == pytest.approx(0.0, abs=1e-12)  # in the body x-y plane
            np.testing.assert_allclose(local, [dx * arm, dy * arm, 0.0], atol=1e-12)
            np.testing.assert_allclose(rotor.rotation, center.rotation, atol=1e-12)


def _u(a: float) -> np.ndarray:
    """u(a) = (cos a, sin a) in the (y, z) plane, as a 3-vector."""
    return np.array([0.0, np.cos(a), np.sin(a)])


def test_fpr_chain_follows_design_conventions():
    model = _load_pinocchio("fpr")
    data = model.createData()
    length = PARAMS["link_length"]
    p = np.array([0.0, 0.3, -0.2])
    phi, q21, h1, h2 = 5 * np.pi / 4, np.pi / 2, 0.4, -0.7
    q = pin.neutral(model)
    q[:3] = p
    q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(phi, 0.0, 0.0)).coeffs()
    q[model.joints[model.getJointId("drone_1_hinge")].idx_q] = h1
    q[model.joints[model.getJointId("q21")].idx_q] = q21
    q[model.joints[model.getJointId("drone_2_hinge")].idx_q] = h2
    pin.framesForwardKinematics(model, data, q)
    np.testing.assert_allclose(data.oMf[model.getFrameId("end_effector")].translation, p, atol=1e-12)
    np.testing.assert_allclose(
        data.oMf[model.getFrameId("drone_1")].translation, p - length * _u(phi), atol=1e-12
    )
    np.testing.assert_allclose(
        data.oMf[model.getFrameId("drone_2")].translation, p - length * _u(phi + q21), atol=1e-12
    )
    # the drones' absolute roll is the link angle plus the hinge angle
    for drone, roll in (("drone_1", phi + h1), ("drone_2", phi + q21 + h2)):
        np.testing.assert_allclose(
            data.oMf[model.getFrameId(drone)].rotation, pin.rpy.rpyToMatrix(roll, 0.0, 0.0), atol=1e-12
        )


def test_prototype_chain_follows_design_conventions():
    model = _load_pinocchio("prototype")
    data = model.createData()
    length = PARAMS["link_length"]
    q1, q2 = -0.9470, 1.8940
    q = pin.neutral(model)
    q[model.joints[model.getJointId("q1")].idx_q] = q1
    q[model.joints[model.getJointId("q2")].idx_q] = q2
    pin.framesForwardKinematics(model, data, q)
    joint_2 = length * _u(q1)
    np.testing.assert_allclose(data.oMf[model.getFrameId("link_2")].translation, joint_2, atol=1e-12)
    np.testing.assert_allclose(data.oMf[model.getFrameId("end_effector")].translation, joint_2, atol=1e-12)
    np.testing.assert_allclose(
        data.oMf[model.getFrameId("drone_1")].translation, joint_2 + length * _u(q1 + q2), atol=1e-12
    )
