"""Crossing the prototype's Type-2 singularity (seed ch. 4): the crossing NLP and the ways of solving it."""
