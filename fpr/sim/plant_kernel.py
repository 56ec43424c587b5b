"""The compiled plant step's side in Python: the extension (``fpr/sim/_plant.c``, None when it is not built) and
the model's numbers it reads (:func:`plant_constants`). :class:`fpr.sim.plant.Plant` chooses between it and
its Python steps (``Plant.compiled_step``)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from fpr.model.compiled import load_extension

#: the extension module fpr.sim._plant, or None when it was not built
kernel = load_extension("fpr.sim._plant")

#: the joints fpr/sim/_plant.c knows: Pinocchio's short name -> (type code, axis in the joint frame)
_COMPILED_JOINTS = {"JointModelRX": (0, (1.0, 0.0, 0.0)), "JointModelRY": (0, (0.0, 1.0, 0.0)),
                    "JointModelRZ": (0, (0.0, 0.0, 1.0)), "JointModelFreeFlyer": (1, (0.0, 0.0, 0.0))}


def plant_constants(closed) -> np.ndarray | None:
    """The closed chain's model (a :class:`~fpr.model.constrained.ClosedChainModel`) as the constants vector of
    the compiled plant (``fpr/sim/_plant.c``), or None when it holds what that code does not know (a joint other than a revolute about a frame axis or a free
    flyer, a loop closure other than a 3D point contact, more than 16 joints, 48 velocities or 4 closures).

    Layout: nj, nq, nv, number of closures, gravity (3), mu, max_iter, absolute and relative accuracy of the
    proximal solve (``closed.settings``); the armature (nv); per joint after the universe: type (0 revolute,
    1 free flyer), parent, idx_q, idx_v, axis (3), placement rotation (9, row-major) and translation (3),
    mass, lever (3), rotational inertia about the centre of mass (9); per closure: joint1, its point (3),
    joint2, its point (3), Baumgarte Kp, Kd.
    """
    model = closed.model
    if model.njoints > 16 or model.nv > 48 or len(closed.constraints) > 4:
        return None
    settings = closed.settings
    values = [model.njoints, model.nq, model.nv, len(closed.constraints), *model.gravity.linear,
              settings.mu, settings.max_iter, settings.absolute_accuracy, settings.relative_accuracy,
              *model.armature]
    for i in range(1, model.njoints):
        joint = model.joints[i]
        known = _COMPILED_JOINTS.get(joint.shortname())
        if known is None:
            return None
        placement, inertia = model.jointPlacements[i], model.inertias[i]
        values += [known[0], model.parents[i], joint.idx_q, joint.idx_v, *known[1],
                   *placement.rotation.reshape(-1), *placement.translation,
                   inertia.mass, *inertia.lever, *inertia.inertia.reshape(-1)]
    for cm in closed.constraints:
        if cm.type != pin.ContactType.CONTACT_3D or cm.reference_frame == pin.ReferenceFrame.WORLD:
            return None
        gains = cm.m_baumgarte_parameters
        values += [cm.joint1_id, *cm.joint1_placement.translation, cm.joint2_id, *cm.joint2_placement.translation,
                   gains.Kp, gains.Kd]
    return np.ascontiguousarray(values, dtype=float)


__all__ = ["kernel", "plant_constants"]
