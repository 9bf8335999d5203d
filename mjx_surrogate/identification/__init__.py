"""Identification: from simulations of the black box to models of it.

Rollouts batched over samples (:mod:`.rollout`), data sets around a trajectory
(:mod:`.data`), the LTV least-squares schemes and their knots, t-test and reduced-order
forms (:mod:`.sysid` and its companions), and one step-model interface over every model
(:mod:`.step_models`). Imports :mod:`mjx_surrogate.systems` and the foundation modules only.
"""
