"""Beyond the paper: identification error against the horizon on the 6-link swimmer (D2C
2.0's task and solver settings, configs/swimmer6_d2c.py: nose -> (0.5, -0.6), T 800).
300 rollouts per level, open loop and under the optimum's gains, identified per step;
reference Jacobians by central differences of the native step."""

import dataclasses

from configs.swimmer6_d2c import CONFIG as _D2C  # the same system, task and solver
from mjx_surrogate.runs.config import DataConfig, ExperimentConfig

CONFIG = dataclasses.replace(
    _D2C,
    system=dataclasses.replace(_D2C.system, backend="native"),
    experiment=ExperimentConfig(kind="horizon", x64=True, oracle="finite_difference"),
    data=DataConfig(n_traj=300, levels=(0.01, 0.05, 0.25)),
)
