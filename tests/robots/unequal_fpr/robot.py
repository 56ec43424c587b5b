"""A third robot, outside the library: the FPR with unequal links and different drones (a test fixture).

This module and ``unequal_fpr.urdf.xacro`` beside it are all the robot needs; a test registers it with
``fpr.robots.register(UnequalFpr)`` and then loads, plans and simulates it by name. Being an FPR, it
takes its kinematics, margins, closure and controller specifics from :class:`fpr.robots.fpr.Fpr`, which
reads one length per link and one mass and hinge offset per drone from the URDF.
"""

from __future__ import annotations

from pathlib import Path

from fpr.robots.fpr import Fpr


class UnequalFpr(Fpr):
    """The FPR with link 1 = 0.9 m, link 2 = 0.6 m, and a heavier drone 2 (1.3 kg) hinged 0.05 m below its CoM."""

    name = "unequal_fpr"
    xacro = Path(__file__).with_name("unequal_fpr.urdf.xacro")
    urdf = None  # generated from the xacro file at every load
    mass_parameters = Fpr.mass_parameters + ("link_2_mass", "drone_2_mass")
    titles = {key: f"{title} (unequal FPR)" for key, title in Fpr.titles.items()}
