"""Controllers of the FPR and the prototype (seed ch. 2.2).

* :mod:`controllers.ctc`: the cascaded computed-torque controller (outer chain loop, attitude loop).
* :mod:`controllers.allocation`: the rotor allocation as a box-constrained QP solved by ProxQP.
"""
