"""The model layer: the robot description, its Pinocchio model in the thesis' coordinates, kinematics, dynamics,
inverse dynamics, rotors, the closed-chain formulation, exact derivatives (jets) and the toolkit's errors.

Nothing here imports a higher layer (``fpr.robots``, ``planners``, ``controllers``, ``fpr.sim``, ``fpr.views``,
``fpr.cli``).
"""
