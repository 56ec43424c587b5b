"""The simulation layer: the plant (the closed-chain model integrated in time, rotors, wind) and the closed loop
(:func:`fpr.sim.closed_loop.simulate`: a plan tracked by the controller on the plant).
"""
