"""Control: Riccati recursions, iLQR and the local models it is driven by, D2C, MPC.

The solvers see only functions (a step, a cost, an identification scheme). Imports
:mod:`mjx_surrogate.identification`, :mod:`mjx_surrogate.surrogates`,
:mod:`mjx_surrogate.systems` and the foundation modules only.
"""
