"""D2C 2.0 cartpole: theta = pi - 0.3 -> upright at the origin, T 30.
The model runs at D2C 2.0's time step (timestep=0.1, substeps=1), so that times and costs compare.
Identification: 10 forward differences on an orthogonal design and 6 step sizes, in float64:
D2C 2.0's optimum with 3.0-3.5x fewer simulations than its 25 central differences on every
key tried (docs/performance.md, "Simulations to the optimum"); in float32 two keys of five
stop at a second stationary point. ``--sysid.scheme central_difference --sysid.n_samples 25
--sysid.design gaussian --solver.n_alphas 8`` is D2C 2.0's LLS-CD.
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
    system=SystemConfig(name="cartpole", timestep=0.1, substeps=1),
    task=TaskConfig(preset="cartpole_d2c"),
    solver=SolverConfig(
        n_alphas=6,
        init="random",
        init_scale=0.1,
        max_iter=300,
        rel_tol=1e-6,
    ),
    sysid=SysIdConfig(scheme="forward_difference", design="orthogonal", n_samples=10),
    experiment=ExperimentConfig(kind="d2c", x64=True),
)
