r"""Inverse dynamics and thrust vectors of a spatial chain along a motion, with exact time derivatives.

The chain is a Pinocchio tree whose joints are made of 1-DoF parts: revolute about any axis, prismatic along any
axis, and composite joints of such parts (the FPR's root, translations then Z-Y-X angles). Its numbers are not typed
in: placements, axes, masses, centres of mass and inertias are read from the Pinocchio model. Given a motion
q(t) as a :class:`~fpr.model.jets.Jet` of order K (one coordinate per part: an angle or a length), a forward pass
gives every part's placement as a jet (R_j, p_j in world axes), each body its Newton-Euler wrench about the world's
origin,

.. math:: f_b = m_b (\ddot c_b - g), \qquad
          \tau_b = c_b \times f_b + I_b \dot\omega_b + \omega_b \times I_b \omega_b,

and a backward sum over subtrees projects them on the parts' axes (world axis a_j through o_j):

.. math:: b_j = a_j \cdot (\tau_{sub(j)} - o_j \times f_{sub(j)}) \ \text{(revolute)}, \qquad
          b_j = a_j \cdot f_{sub(j)} \ \text{(prismatic)},

which is ``M q'' + c`` (gravity included), Pinocchio's ``rnea``. The tips' Jacobian (world axes) comes from the same
pass, column j of tip i being a_j x (s_i - o_j) (revolute) or a_j (prismatic) on the tip's support, and the forces
the tips must receive (the drones' thrust vectors of a chain carrying point drones at its tips) are
F = J^-T b, a jet of order K - 2: F, F', F'' from a motion of order 4, exactly (Taylor arithmetic).

Every operation is a :mod:`fpr.model.jets` one, batched over samples and over the parts of one depth of the tree
(the legs of a parallel robot go together), so the values may be complex (complex-step differentiation) or the jets'
arrays :class:`~fpr.model.dual.Dual` numbers.

Example:
    >>> import pinocchio as pin
    >>> model = pin.buildSampleModelManipulator()
    >>> chain = SpatialChain(model, [model.frames[-1].name])
    >>> q = Jet(np.stack([np.full((2, model.nv), 0.3), np.ones((2, model.nv)), np.zeros((2, model.nv))]))
    >>> chain.generalized_forces(q).shape
    (2, 6)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from fpr.model import jets
from fpr.model.errors import ModelArgumentError, RobotDefinitionError
from fpr.model.jets import Jet

_UNIT = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
_NEXT, _AFTER = [1, 2, 0], [2, 0, 1]  # the vee of a skew matrix: (W32, W13, W21)
_SKEW = np.cross(np.eye(3)[:, None, :], -np.eye(3)[None]).reshape(3, 9)  # v @ _SKEW = [v]x (row-major)


@dataclass(frozen=True)
class Part:
    """A 1-DoF part of a joint of the tree.

    Attributes:
        parent: index of the parent part (in :attr:`SpatialChain.parts`), -1 for the world.
        rotation: the part's placement in its parent's frame at q = 0, rotation (3, 3).
        translation: the same placement's translation (3,) [m].
        axis: unit axis of the part in its own frame (3,).
        revolute: True for a rotation about the axis, False for a translation along it.
        index: the part's coordinate (velocity index in the Pinocchio model).
        joint: the Pinocchio joint id the part belongs to.
    """

    parent: int
    rotation: np.ndarray
    translation: np.ndarray
    axis: np.ndarray
    revolute: bool
    index: int
    joint: int


def _part_kind(joint, model: pin.Model, name: str) -> tuple[bool, np.ndarray]:
    """(revolute, axis) of a 1-DoF Pinocchio joint model (a part of the joint ``name`` of ``model``);
    RobotDefinitionError for other joints.
    """
    name = joint.shortname().removeprefix("JointModel")
    for prefix, revolute in (("RUB", True), ("R", True), ("P", False)):
        if name[len(prefix):] in _UNIT and name.startswith(prefix):
            return revolute, np.array(_UNIT[name[len(prefix):]])
    for prefix, revolute in (("RevoluteUnboundedUnaligned", True), ("RevoluteUnaligned", True),
                             ("PrismaticUnaligned", False)):
        if name == prefix:
            axis = np.asarray(joint.extract().axis, float)
            return revolute, axis / np.linalg.norm(axis)
    raise RobotDefinitionError(model.name or "the model", f"joint {name} of kind {joint.shortname()}: a spatial chain "
                               f"takes joints made of revolute or prismatic parts (and composite joints of them); "
                               f"write the joint as such parts")


def tree_parts(model: pin.Model) -> tuple[list[Part], dict[int, int]]:
    """The tree's 1-DoF parts in Pinocchio's joint order (composite joints expanded) and, per joint id, the index
    of its last part (the part that carries the joint's body).
    """
    parts: list[Part] = []
    last = {0: -1}
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        if joint.shortname() == "JointModelComposite":
            composite = joint.extract()
            subs = list(zip(composite.joints, composite.jointPlacements, strict=True))
        else:
            subs = [(joint, pin.SE3.Identity())]
        parent = last[model.parents[jid]]
        for k, (sub, inner) in enumerate(subs):
            placement = model.jointPlacements[jid] * inner if k == 0 else inner
            revolute, axis = _part_kind(sub, model, model.names[jid])
            parts.append(Part(parent, placement.rotation.copy(), placement.translation.copy(), axis, revolute,
                              joint.idx_v + k, jid))
            parent = len(parts) - 1
        last[jid] = len(parts) - 1
    return parts, last


def _cross(a: Jet, b: Jet) -> Jet:
    """a x b along the last axis (Jets, broadcast) as [a]x b: a jets' matrix product (native, and one batched
    product for dual numbers, where elementwise products of Duals cost more).
    """
    return jets.matvec(_skew(a), b)


def _skew(a: Jet) -> Jet:
    """[a]x (..., 3, 3) of a Jet (..., 3)."""
    return jets.matmul(a, _SKEW).reshape(a.shape[:-1] + (3, 3))


def _dot(a: Jet, b: Jet) -> Jet:
    """a . b along the last axis (Jets, broadcast) as a jets' matrix product."""
    return jets.matmul(a[..., None, :], b[..., :, None])[..., 0, 0]


@dataclass(frozen=True)
class _Level:
    """The parts of one depth of the tree, as constants for one batched step of the forward pass."""

    parts: np.ndarray  # indices into the chain's parts (sorted by level)
    parents: np.ndarray | None  # positions of their parents in the previous level (None: the world)
    coordinates: np.ndarray  # the parts' coordinates
    fixed: np.ndarray  # X A0: R_local = fixed + sin * sine + cos * cosine (revolute parts; X for prismatic ones)
    sine: np.ndarray
    cosine: np.ndarray
    slide: np.ndarray  # X a for prismatic parts, 0 for revolute ones: t_local = translation + slide q
    translation: np.ndarray
    revolute: bool  # some part of the level is revolute


@dataclass(frozen=True)
class SpatialMotion:
    """What a motion asks of the chain (:meth:`SpatialChain.evaluate`), jets of order K - 2.

    Attributes:
        b: generalised forces M q'' + c (gravity included), shape (..., nv).
        jacobian: the tips' Jacobian in world axes, shape (..., 3 n_tips, nv).
        forces: the forces on the tips, J^-T b, shape (..., n_tips, 3) [N] (None when J is not square).
    """

    b: Jet
    jacobian: Jet
    forces: Jet | None


class SpatialChain:
    """The jets model of a Pinocchio tree of 1-DoF parts with tips (see the module's description).

    Args:
        model: the Pinocchio model (a point drone is a point mass on the body that carries its tip).
        tips: the tips' frame names (or ids); their forces are the thrust vectors.
        gravity: the gravity vector [m/s^2] (default: the model's).

    Coordinates: one per velocity of the model, in Pinocchio's velocity order (the angle of a revolute joint, even
    an unbounded one Pinocchio writes as a cosine and a sine).
    """

    def __init__(self, model: pin.Model, tips, gravity=None):
        self.parts, last = tree_parts(model)
        if sorted(p.index for p in self.parts) != list(range(model.nv)):
            raise RobotDefinitionError(model.name or "the model", f"its {model.nv} velocities are not one per 1-DoF "
                                                                  f"part of its joints")
        self.nv = model.nv
        self.gravity = np.asarray(model.gravity.linear if gravity is None else gravity, float)
        depth = []
        for p in self.parts:
            depth.append(0 if p.parent < 0 else depth[p.parent] + 1)
        order = sorted(range(len(self.parts)), key=lambda k: (depth[k], k))  # level by level
        self.parts = [self.parts[k] for k in order]
        renumber = {old: new for new, old in enumerate(order)} | {-1: -1}
        self.parts = [Part(renumber[p.parent], p.rotation, p.translation, p.axis, p.revolute, p.index, p.joint)
                      for p in self.parts]
        last = {j: renumber[k] for j, k in last.items()}
        depth = [depth[k] for k in order]
        self._levels = self._make_levels(depth)
        n = len(self.parts)
        self._column = np.argsort([p.index for p in self.parts])  # velocity v -> part
        self._axis = np.array([p.axis for p in self.parts])
        self._revolute = np.array([p.revolute for p in self.parts], float)[:, None]
        # bodies: the inertia of each joint on its last part
        bodies = [(last[j], model.inertias[j]) for j in range(1, model.njoints)
                  if model.inertias[j].mass > 0 or np.any(model.inertias[j].inertia)]
        self._body_part = np.array([k for k, _ in bodies], int)
        self._mass = np.array([i.mass for _, i in bodies])[:, None]
        self._lever = np.array([i.lever for _, i in bodies]).reshape(-1, 3)
        self._inertia = np.array([i.inertia for _, i in bodies]).reshape(-1, 3, 3)
        ancestors = [self._support(k) for k in range(n)]
        self._subtree = np.array([[float(j in ancestors[k]) for k in self._body_part] for j in range(n)])
        # tips: the part that carries each frame, its position there, the parts that support it
        ids = [t if isinstance(t, (int, np.integer)) else model.getFrameId(t) for t in tips]
        if any(i >= model.nframes for i in ids):
            raise ModelArgumentError("tips", list(tips), "give frame names (or ids) of the model")
        self.tips = [model.frames[i].name for i in ids]
        self._tip_part = np.array([last[model.frames[i].parentJoint] for i in ids], int)
        if np.any(self._tip_part < 0):
            raise ModelArgumentError("tips", self.tips, "give frames on moving bodies")
        self._tip_point = np.array([model.frames[i].placement.translation for i in ids]).reshape(-1, 3)
        support = np.array([[float(j in ancestors[k]) for j in range(n)] for k in self._tip_part])
        self._tip_revolute = (support * self._revolute[:, 0])[:, None, :]  # (n_tips, 1, n_parts)
        self._tip_prismatic = (support * (1.0 - self._revolute[:, 0]))[:, None, :]

    def _support(self, k: int) -> set[int]:
        """The parts from part k to the root."""
        out = set()
        while k >= 0:
            out.add(k)
            k = self.parts[k].parent
        return out

    def _make_levels(self, depth) -> list[_Level]:
        levels = []
        position = {}
        for level in range(max(depth) + 1):
            members = np.array([k for k, d in enumerate(depth) if d == level], int)
            for i, k in enumerate(members):
                position[k] = i
            parts = [self.parts[k] for k in members]
            x = np.array([p.rotation for p in parts])
            a = np.array([p.axis for p in parts])
            rev = np.array([p.revolute for p in parts])
            outer = a[:, :, None] * a[:, None, :]
            skew = np.cross(a[:, None, :], -np.eye(3)[None])  # [a]x: [a]x v = a x v
            ident = np.broadcast_to(np.eye(3), outer.shape)
            fixed = np.where(rev[:, None, None], x @ outer, x)
            sine = np.where(rev[:, None, None], x @ skew, 0.0)
            cosine = np.where(rev[:, None, None], x @ (ident - outer), 0.0)
            slide = np.where(rev[:, None], 0.0, np.einsum("kij,kj->ki", x, a))
            parents = None if level == 0 else np.array([position[p.parent] for p in parts], int)
            levels.append(_Level(members, parents, np.array([p.index for p in parts], int), fixed, sine, cosine, slide,
                                 np.array([p.translation for p in parts]), bool(rev.any())))
        return levels

    # ------------------------------------------------------------------------------------------ passes
    def placements(self, q: Jet) -> tuple[Jet, Jet]:
        """Every part's frame in the world along the motion: rotations (..., n_parts, 3, 3) and origins
        (..., n_parts, 3), jets of q's order, parts in :attr:`parts`' order (level by level).
        """
        if not isinstance(q, Jet) or q.shape[-1:] != (self.nv,):
            raise ModelArgumentError("q", getattr(q, "shape", None), f"give a Jet of shape (..., {self.nv})")
        rotations, origins = [], []
        for level in self._levels:
            angle = q[..., level.coordinates]
            rotation = level.fixed
            if level.revolute:
                s, c = jets.sincos(angle)
                rotation = s[..., None, None] * level.sine + c[..., None, None] * level.cosine + level.fixed
            else:
                rotation = Jet.constant(np.broadcast_to(rotation, angle.shape + (3, 3)), q.order)
            shift = angle[..., None] * level.slide + level.translation
            if level.parents is None:
                rotations.append(rotation)
                origins.append(shift)
                continue
            parent_r = rotations[-1][..., level.parents, :, :]
            parent_p = origins[-1][..., level.parents, :]
            rotations.append(parent_r @ rotation)
            origins.append(parent_p + jets.matvec(parent_r, shift))
        return jets.concatenate(rotations, axis=-3), jets.concatenate(origins, axis=-2)

    def _wrenches(self, rotation: Jet, origin: Jet) -> tuple[Jet, Jet]:
        """Each body's Newton-Euler force and moment about the world's origin (..., n_bodies, 3), order K - 2."""
        K = rotation.order
        if K < 2:
            raise ModelArgumentError("q", K, "give a motion of order 2 or more (q, q', q'' at least)")
        r = rotation[..., self._body_part, :, :]
        centre = origin[..., self._body_part, :] + jets.matvec(r, self._lever)
        force = (centre.derivative().derivative() - self.gravity) * self._mass
        spin = r.derivative() @ r.truncate(K - 1).mT  # [w]x in world axes, order K - 1
        w = spin[..., _AFTER, _NEXT]  # (W32, W13, W21)
        r2 = r.truncate(K - 2)
        inertia = r2 @ self._inertia @ r2.mT
        w2 = w.truncate(K - 2)
        moment = jets.matvec(inertia, w.derivative()) + _cross(w2, jets.matvec(inertia, w2))
        return force, _cross(centre.truncate(K - 2), force) + moment

    def evaluate(self, q: Jet, forces: bool = True) -> SpatialMotion:
        """b = M q'' + c, the tips' Jacobian and (``forces``, J square) the tips' forces along the motion q.

        Args:
            q: the motion, a Jet of order K >= 2 and shape (..., nv) (values real, complex or Duals).
            forces: solve for the tips' forces (requires 3 n_tips == nv).

        Returns:
            :class:`SpatialMotion`, jets of order K - 2.
        """
        rotation, origin = self.placements(q)
        K = q.order - 2
        force, moment = self._wrenches(rotation, origin)
        f_sub, m_sub = jets.matmul(self._subtree, force), jets.matmul(self._subtree, moment)
        axis = jets.matvec(rotation.truncate(K), self._axis)  # world axes (..., n_parts, 3)
        moment_arm = _cross(origin.truncate(K), axis)  # o x a: a . (o x f) = -(o x a) . f
        b = (_dot(axis * self._revolute, m_sub) + _dot(moment_arm * self._revolute + axis * (1.0 - self._revolute),
                                                         f_sub))[..., self._column]
        jacobian = self._jacobian(rotation.truncate(K), origin.truncate(K), axis, moment_arm)
        if not forces:
            return SpatialMotion(b, jacobian, None)
        if 3 * len(self.tips) != self.nv:
            raise ModelArgumentError("forces", forces, f"J^T is {self.nv} x {3 * len(self.tips)}, not square: "
                                                       f"ask for b and J only (forces=False)")
        f = jets.solve(jacobian.mT, b)
        return SpatialMotion(b, jacobian, f.reshape(f.shape[:-1] + (len(self.tips), 3)))

    def _jacobian(self, rotation: Jet, origin: Jet, axis: Jet, moment_arm: Jet) -> Jet:
        """The tips' Jacobian (..., 3 n_tips, nv) from the parts' frames, world axes a and o x a.

        Column j of tip i is a_j x (s_i - o_j) = o_j x a_j - [s_i]x a_j (revolute) or a_j (prismatic): one matrix
        product per tip for all parts (the jets' products, not elementwise cross products).
        """
        tip = origin[..., self._tip_part, :] + jets.matvec(rotation[..., self._tip_part, :, :], self._tip_point)
        a = axis.mT[..., None, :, :]  # (..., 1, 3, n_parts)
        turn = moment_arm.mT[..., None, :, :] - _skew(tip) @ a  # [s_i]x (..., n_tips, 3, 3) times the axes
        columns = turn * self._tip_revolute + a * self._tip_prismatic  # (..., n_tips, 3, n_parts)
        columns = columns[..., self._column]
        return columns.reshape(columns.shape[:-3] + (3 * len(self.tips), self.nv))

    def generalized_forces(self, q: Jet) -> Jet:
        """b = M q'' + c (gravity included) along the motion q, a Jet (..., nv) of order K - 2."""
        return self.evaluate(q, forces=False).b

    def thrusts(self, q: Jet) -> Jet:
        """The tips' forces F = J^-T b along the motion q, a Jet (..., n_tips, 3) of order K - 2 [N]."""
        return self.evaluate(q).forces

    def tip_jacobian(self, q) -> np.ndarray:
        """The tips' Jacobian (..., 3 n_tips, nv) in world axes at configurations q (..., nv) (an array)."""
        q = np.asarray(q) if not isinstance(q, Jet) else q.value
        jet = Jet(q[None])
        rotation, origin = self.placements(jet)
        axis = jets.matvec(rotation, self._axis)
        return self._jacobian(rotation, origin, axis, _cross(origin, axis)).value
