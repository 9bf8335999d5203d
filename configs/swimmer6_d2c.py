"""D2C 2.0 swimmer6: nose -> (0.5, -0.6), T 800, 25 samples per identification.
The model runs at D2C 2.0's time step (timestep=0.01, substeps=1), so that times and costs compare.
Up to 500 iterations (D2C 2.0 stopped at 250): from the benchmark's start, 1632.7 at 500 against
1630.8 fully converged (561). Central differences: with joint limits active, forward
differences stall above the optimum (docs/performance.md).
"""

from mjx_surrogate.runs.config import (
    Config,
    ExperimentConfig,
    SolverConfig,
    SysIdConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="swimmer6", timestep=0.01, substeps=1),
    task=TaskConfig(preset="swimmer6_d2c"),
    solver=SolverConfig(
        init="random",
        init_scale=0.1,
        max_iter=500,
        rel_tol=1e-7,
    ),
    sysid=SysIdConfig(scheme="central_difference", n_samples=25, sigma_x=1e-5, sigma_u=1e-5),
    # The exact oracle needs MJX through 800 steps of a 6-link chain: impractical on 2 CPU
    # cores (docs/performance.md); turn it on with --experiment.exact_oracle True on a GPU.
    experiment=ExperimentConfig(kind="d2c", exact_oracle=False, x64=True),
)
