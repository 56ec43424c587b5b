"""Replanning in flight: re-optimise the rest of the motion and splice it C4 into the plan in force."""
