"""D2C 2.0 swimmer6: nose -> (0.5, -0.6), T 800, 25 samples per identification."""
from mjx_surrogate.config import Config, ExperimentConfig, SolverConfig, SystemConfig, TaskConfig

CONFIG = Config(
    system=SystemConfig(name="swimmer6"),
    task=TaskConfig(preset="swimmer6_d2c"),
    solver=SolverConfig(sysid="central_difference", n_samples=25, init="random", init_scale=0.1,
                        max_iter=250, rel_tol=1e-5),
    experiment=ExperimentConfig(kind="d2c"),
)
