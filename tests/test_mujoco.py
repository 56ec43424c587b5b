"""The committed URDFs read by another simulator: MuJoCo loads them as they are and agrees with Pinocchio.

MuJoCo is an independent rigid-body implementation (its own URDF reader, composite-rigid-body algorithm
and recursive Newton-Euler), so equal mass matrices and bias forces at random configurations check
the description and Pinocchio's reading of it together: the joints' order, axes and placements, and
every mass, centre of mass and inertia.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from fpr.model import description

mujoco = pytest.importorskip("mujoco", reason="mujoco is in the test extra: pip install -e .[test]")

ROBOTS = ("fpr", "prototype")


def _mujoco_model(robot: str, text: str | None = None):
    if text is None:
        return mujoco.MjModel.from_xml_path(str(description.urdf_path(robot)))
    return mujoco.MjModel.from_xml_string(text)


def _pinocchio_model(text: str) -> pin.Model:
    # Both simulators see the URDF's root link fixed in the world (MuJoCo adds no free joint to a URDF).
    model = pin.buildModelFromXML(description.single_angle_urdf(text))
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    return model


def _dense_mass_matrix(mj, data) -> np.ndarray:
    full = np.zeros((mj.nv, mj.nv))
    if hasattr(data, "qM"):  # MuJoCo 3: mj_fullM(m, dst, M)
        mujoco.mj_fullM(mj, full, data.qM)
    else:  # MuJoCo 4: mj_fullM(m, d, dst)
        mujoco.mj_fullM(mj, data, full)
    return full


def _compare_dynamics(robot: str, text: str, samples: int = 8):
    """Largest differences of M(q) and of the bias forces c(q, v) + g(q) between MuJoCo and Pinocchio."""
    mj = _mujoco_model(robot, text)
    mj.opt.gravity[:] = (0.0, 0.0, -9.81)
    data = mujoco.MjData(mj)
    model = _pinocchio_model(text)
    pdata = model.createData()
    assert mj.nq == mj.nv == model.nq == model.nv
    rng = np.random.default_rng(7)
    worst_m = worst_b = 0.0
    scale_m = scale_b = 0.0
    for _ in range(samples):
        q = rng.uniform(-np.pi, np.pi, model.nq)
        v = rng.uniform(-3.0, 3.0, model.nv)
        data.qpos[:] = q
        data.qvel[:] = v
        mujoco.mj_forward(mj, data)
        full = _dense_mass_matrix(mj, data)
        m = pin.crba(model, pdata, q)
        m = np.triu(m) + np.triu(m, 1).T
        b = pin.rnea(model, pdata, q, v, np.zeros(model.nv))
        worst_m = max(worst_m, float(np.max(np.abs(full - m))))
        worst_b = max(worst_b, float(np.max(np.abs(data.qfrc_bias - b))))
        scale_m = max(scale_m, float(np.max(np.abs(m))))
        scale_b = max(scale_b, float(np.max(np.abs(b))))
    return worst_m, worst_b, scale_m, scale_b


@pytest.mark.parametrize("robot", ROBOTS)
def test_mujoco_loads_the_committed_urdf_unmodified(robot):
    """The file as committed: every hinge continuous and unlimited, the joints in Pinocchio's order."""
    mj = _mujoco_model(robot)
    text = description.urdf_path(robot).read_text(encoding="utf-8")
    model = _pinocchio_model(text)
    assert [mj.joint(i).name for i in range(mj.njnt)] == list(model.names[1:])
    assert not any(mj.jnt_limited), "a passive hinge became a limited joint"
    kinds = {joint.get("type") for joint in ET.fromstring(text).iter("joint")}
    assert kinds <= {"continuous", "fixed"}, kinds


@pytest.mark.parametrize("robot", ROBOTS)
def test_mujoco_and_pinocchio_agree_on_mass_matrix_and_bias(robot):
    """M(q) and c(q, v) + g(q) at random states: the same to rounding in both simulators."""
    text = description.urdf_path(robot).read_text(encoding="utf-8")
    worst_m, worst_b, scale_m, scale_b = _compare_dynamics(robot, text)
    assert scale_m > 0.1 and scale_b > 1.0  # the comparison is not between zeros
    assert worst_m < 1e-9 * max(1.0, scale_m), worst_m
    assert worst_b < 1e-9 * max(1.0, scale_b), worst_b


def test_mujoco_sees_a_changed_parameter():
    """A variant (heavier drone, hinge at the centre of mass) still agrees: the test is not tuned to one file."""
    text = description.generate_urdf("prototype", drone_mass=1.7, hinge_offset=0.0)
    worst_m, worst_b, _, _ = _compare_dynamics("prototype", text, samples=4)
    assert worst_m < 1e-9 and worst_b < 1e-8
    default = description.urdf_path("prototype").read_text(encoding="utf-8")
    assert _compare_dynamics("prototype", default, samples=1)[0] < 1e-9
    # and the two descriptions do differ in MuJoCo's eyes
    a, b = _mujoco_model("prototype", text), _mujoco_model("prototype", default)
    assert abs(float(np.sum(a.body_mass)) - float(np.sum(b.body_mass)) - 0.7) < 1e-12


@pytest.mark.parametrize("robot", ROBOTS)
def test_no_zero_size_geometry_when_the_hinge_is_at_the_centre(robot):
    """hinge_offset = 0 leaves out the strut instead of writing a cylinder of length 0."""
    text = description.generate_urdf(robot, hinge_offset=0.0)
    for element in ET.fromstring(text).iter():
        for key in ("radius", "length"):
            if element.tag in ("cylinder", "sphere") and key in element.attrib:
                assert float(element.get(key)) > 0, (element.tag, element.attrib)
        if element.tag == "box":
            assert all(float(s) > 0 for s in element.get("size").split())
    assert "_strut" not in text
    assert "_strut" in description.generate_urdf(robot, hinge_offset=0.05)
    _mujoco_model(robot, text)  # loads


def test_moving_links_carry_mass():
    """Every link below a joint that moves has a positive mass (MuJoCo refuses others)."""
    for robot in ROBOTS:
        root = ET.fromstring(description.urdf_path(robot).read_text(encoding="utf-8"))
        moving = {j.find("child").get("link") for j in root.iter("joint") if j.get("type") != "fixed"}
        for link in root.iter("link"):
            if link.get("name") in moving:
                mass = link.find("inertial/mass")
                assert mass is not None and float(mass.get("value")) > 0, (robot, link.get("name"))


def test_single_angle_urdf_changes_only_continuous_joints():
    """The Pinocchio reading: one coordinate per hinge, everything else byte for byte."""
    text = description.urdf_path("prototype").read_text(encoding="utf-8")
    converted = description.single_angle_urdf(text)
    assert 'type="continuous"' not in converted
    assert converted.count('type="revolute"') == text.count('type="continuous"') == 5
    with pytest.raises(ValueError):
        pin.buildModelFromXML("<robot name='x'/>")  # Pinocchio rejects an empty model: the reader is real
    model = pin.buildModelFromXML(converted)
    raw = pin.buildModelFromXML(text)
    assert model.nq == model.nv == raw.nv == 5 and raw.nq == 10  # Pinocchio's own reading: (cos, sin) pairs
    stripped = converted
    for joint in ET.fromstring(converted).iter("joint"):
        if joint.get("type") == "revolute":
            limit = joint.find("limit")
            assert float(limit.get("upper")) >= 1e9 and float(limit.get("lower")) <= -1e9
    assert len(stripped.splitlines()) == len(text.splitlines())
