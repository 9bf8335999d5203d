"""Beyond the paper: identification error against the horizon on the 6-link swimmer (D2C
2.0's task and solver settings, configs/swimmer6_d2c.py: nose -> (0.5, -0.6), T 800).
300 rollouts per level, open loop and under the optimum's gains, identified per step;
reference Jacobians by central differences of the native step."""

from mjx_surrogate.config import Config, DataConfig, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="swimmer6", timestep=0.01, substeps=1, backend="native"),
    task=TaskConfig(preset="swimmer6_d2c"),
    solver=SolverConfig(
        sysid="central_difference",
        n_samples=25,
        init="random",
        init_scale=0.1,
        max_iter=500,
        rel_tol=1e-7,
        sigma_x=1e-5,
        sigma_u=1e-5,
    ),
    experiment=ExperimentConfig(kind="horizon", x64=True, oracle="finite_difference"),
    data=DataConfig(n_traj=300, levels=(0.01, 0.05, 0.25)),
)
