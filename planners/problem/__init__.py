"""The planning NLP: the motion problem and its exact derivatives, the dense check, known external forces."""
