"""CI smoke: MPC on the pendulum, every controller, tiny sizes, noise and a plant that is
heavier, longer and more damped than the model."""

from mjx_surrogate.config import (
    Config,
    DataConfig,
    ExperimentConfig,
    MLPConfig,
    MPCConfig,
    SindyConfig,
    SolverConfig,
    SurrogateConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="pendulum", backend="native"),
    task=TaskConfig(preset="pendulum_d2c", T=8, Q_diag=(9.0, 0.9)),
    solver=SolverConfig(max_iter=30),
    experiment=ExperimentConfig(kind="mpc", progress=False, x64=True, oracle="finite_difference"),
    data=DataConfig(n_traj=40),
    surrogate=SurrogateConfig(
        sindy=SindyConfig(libraries=("cubic_trig",)), mlp=MLPConfig(epochs=3, batch_size=32)
    ),
    mpc=MPCConfig(
        horizon=5,
        steps=6,
        max_iter=2,
        process_noise=(0.0, 0.01),
        plants=("mass=1.2,length=1.1,damping=2",),
        n_episodes=2,
        refit_weight=10.0,
    ),
)
