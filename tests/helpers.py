"""Shared test helpers."""


def random_state(robot, rng, scale=1.0):
    """A random configuration near the reference pose of ``robot`` and a random velocity of size ``scale``."""
    q = 0.3 * rng.normal(size=robot.nq)
    q[robot.indices(robot.layout.chain)] += robot.kind.reference_chain
    return q, scale * rng.normal(size=robot.nq)
