"""The solvers of the planning NLPs: the trust-region SQP, its active-set QP, curvature models, stages."""
