"""Beyond the paper: identification error against the horizon on the cartpole swing-up
(the prediction preset's task and optimum). 500 rollouts per level, open loop and under the
optimum's gains, identified per step; reference Jacobians by central differences."""

from mjx_surrogate.config import Config, DataConfig, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="cartpole"),
    task=TaskConfig(preset="cartpole_swingup"),
    solver=SolverConfig(n_samples=25, max_iter=300, rel_tol=1e-6, init="zeros"),
    experiment=ExperimentConfig(kind="horizon", x64=True, oracle="finite_difference"),
    data=DataConfig(n_traj=500, levels=(0.01, 0.05, 0.25)),
)
