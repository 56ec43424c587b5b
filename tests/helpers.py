"""Shared test helpers."""


def random_state(robot, rng, scale=1.0):
    """A random configuration near the reference pose of ``robot`` and a random velocity of size ``scale``."""
    q = 0.3 * rng.normal(size=robot.nq)
    q[robot.indices(robot.layout.chain)] += robot.kind.reference_chain
    return q, scale * rng.normal(size=robot.nq)


# A one-travel prototype mission short enough for campaign tests (tests/test_campaign*.py).
SHORT_HOP = """description = "a short hop of the prototype's drone, for tests"
robot = "prototype"
space = "task"
arm = "down"
way_points = [[1.2, -0.45], [1.2, -0.3]]
times = [1.0]
via_points = 0
alpha = 0.5
"""
