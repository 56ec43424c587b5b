"""Motion planning of the FPR and its prototype (seed ch. 3-4): polynomial segments and their optimisation."""
