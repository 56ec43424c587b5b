"""The compiled plant step's side in Python: the extension (``fpr/model/_multibody.c``, None when it is not built) and
the model's numbers it reads (:func:`plant_constants`). :class:`fpr.sim.plant.Plant` chooses between it and
its Python steps (``Plant.compiled_step``)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from fpr.model.compiled import load_extension

#: the extension module fpr.model._multibody, or None when it was not built
kernel = load_extension("fpr.model._multibody")

#: the joints fpr/model/_multibody.c knows: Pinocchio's short name -> (type code, axis in the joint frame)
_COMPILED_JOINTS = {"JointModelRX": (0, (1.0, 0.0, 0.0)), "JointModelRY": (0, (0.0, 1.0, 0.0)),
                    "JointModelRZ": (0, (0.0, 0.0, 1.0)), "JointModelFreeFlyer": (1, (0.0, 0.0, 0.0)),
                    "JointModelPX": (2, (1.0, 0.0, 0.0)), "JointModelPY": (2, (0.0, 1.0, 0.0)),
                    "JointModelPZ": (2, (0.0, 0.0, 1.0))}
_NO_BODY = [0.0] * 13  # mass, lever, inertia of a composite joint's inner parts
_MAX_JOINTS, _MAX_VELOCITY, _MAX_CLOSURES = 16, 48, 4


def _joint_parts(joint, placement) -> list | None:
    """(type, axis, placement) of a joint's parts, the body on the last: itself, or a composite's sub-joints
    (those with identity placements inside), or None when the C code does not know it."""
    known = _COMPILED_JOINTS.get(joint.shortname())
    if known is not None:
        return [(known, placement)]
    if joint.shortname() != "JointModelComposite":
        return None
    composite = joint.extract()
    parts = []
    for k, (sub, inner) in enumerate(zip(composite.joints, composite.jointPlacements, strict=True)):
        known = _COMPILED_JOINTS.get(sub.shortname())
        if known is None or known[0] == 1 or not inner.isIdentity():
            return None
        parts.append((known, placement if k == 0 else pin.SE3.Identity()))
    return parts


def model_constants(model: pin.Model, constraints=(), settings=None) -> tuple[np.ndarray, dict] | None:
    """A Pinocchio model as the constants vector of ``fpr/model/_multibody.c`` and the map from its joint ids to
    the vector's, or None when it holds what that code does not know: a joint other than a revolute or
    prismatic joint along a frame axis, a free flyer or a composite of the one-degree ones; a loop closure
    other than a 3D point contact; more than 16 joints, 48 velocities or 4 closures; closures under proximal
    settings that code does not take (mu <= 0 or max_iter < 1; Pinocchio's solve with max_iter = 0 is not its
    iterations').

    A composite joint becomes its sub-joints in a row, the body on the last (the same kinematics and
    dynamics: the inner parts have no mass).

    Layout: nj, nq, nv, number of closures, gravity (3), mu, max_iter, absolute and relative accuracy of the
    proximal solve (``settings``, a ``pin.ProximalSettings``; unused without closures); the armature (nv);
    per joint after the universe: type (0 revolute, 1 free flyer, 2 prismatic), parent, idx_q, idx_v, axis
    (3), placement rotation (9, row-major) and translation (3), mass, lever (3), rotational inertia about the
    centre of mass (9); per closure: joint1, its point (3), joint2, its point (3), Baumgarte Kp, Kd.
    """
    if model.nv > _MAX_VELOCITY or len(constraints) > _MAX_CLOSURES:
        return None
    rows, ids = [], {0: 0}
    for i in range(1, model.njoints):
        joint = model.joints[i]
        parts = _joint_parts(joint, model.jointPlacements[i])
        if parts is None:
            return None
        parent, iq, iv = ids[model.parents[i]], joint.idx_q, joint.idx_v
        inertia = model.inertias[i]
        body = [inertia.mass, *inertia.lever, *inertia.inertia.reshape(-1)]
        for k, ((code, axis), placement) in enumerate(parts):
            rows.append([code, parent, iq, iv, *axis, *placement.rotation.reshape(-1), *placement.translation,
                         *(body if k == len(parts) - 1 else _NO_BODY)])
            parent = len(rows)
            iq, iv = iq + (7 if code == 1 else 1), iv + (6 if code == 1 else 1)
        ids[i] = len(rows)
    if len(rows) + 1 > _MAX_JOINTS:
        return None
    if settings is None or not constraints:  # unused without closures (the C code reads valid ones)
        settings = pin.ProximalSettings(1e-12, 1e-9, 1)
    elif not (settings.mu > 0 and settings.max_iter >= 1):
        return None
    values = [len(rows) + 1, model.nq, model.nv, len(constraints), *model.gravity.linear,
              settings.mu, settings.max_iter, settings.absolute_accuracy, settings.relative_accuracy,
              *model.armature]
    for row in rows:
        values += row
    for cm in constraints:
        if cm.type != pin.ContactType.CONTACT_3D or cm.reference_frame == pin.ReferenceFrame.WORLD:
            return None
        gains = cm.m_baumgarte_parameters
        values += [ids[cm.joint1_id], *cm.joint1_placement.translation, ids[cm.joint2_id],
                   *cm.joint2_placement.translation, gains.Kp, gains.Kd]
    return np.ascontiguousarray(values, dtype=float), ids


def plant_constants(closed) -> np.ndarray | None:
    """The closed chain's model (a :class:`~fpr.model.constrained.ClosedChainModel`) with its loop closures and
    proximal settings as the constants of the compiled plant (:func:`model_constants`), or None."""
    exported = model_constants(closed.model, closed.constraints, closed.settings)
    return None if exported is None else exported[0]


__all__ = ["kernel", "model_constants", "plant_constants"]
