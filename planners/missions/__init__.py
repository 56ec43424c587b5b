"""Missions: the planner's input (way points, times, via points, weights), their events, the built-in files.

Importing this package imports nothing else (the command lines' ``--help`` reads :data:`BUILTIN_MISSIONS`);
:mod:`planners.missions.mission` reads and checks missions.
"""

BUILTIN_MISSIONS = ("square", "study", "prototype-tour", "cross-singularity", "moving-target", "gust", "fpr3-tour")
"""Names of the built-in missions, files ``planners/missions/<name>.toml``."""
