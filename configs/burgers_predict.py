"""The paper's prediction study on a PDE (``burgers64``, task ``burgers_damp``): around the
D2C optimum, 200 perturbed trajectories per level; SINDy with a quadratic library on the
full field (72 coordinates, 2701 features), SINDy on the leading 8 POD modes (linear and
quadratic libraries), the paper's MLP, and the local LTV model, in full order and in the
data's snapshot basis per t; open-loop prediction error against the perturbation level
(docs/pde.md)."""

from mjx_surrogate.config import (
    Config,
    DataConfig,
    ExperimentConfig,
    MLPConfig,
    PodSindyConfig,
    SindyConfig,
    SurrogateConfig,
    SystemConfig,
    TaskConfig,
)

CONFIG = Config(
    system=SystemConfig(name="burgers64"),
    task=TaskConfig(preset="burgers_damp"),
    experiment=ExperimentConfig(kind="predict"),
    data=DataConfig(n_traj=200, levels=(0.05, 0.10, 0.30, 0.60, 1.00)),
    surrogate=SurrogateConfig(
        kinds=("sindy", "pod_sindy", "mlp"),
        reduced_ltv_tol=1e-8,
        sindy=SindyConfig(libraries=("poly2",)),
        pod_sindy=PodSindyConfig(rank=8, libraries=("poly1", "poly2")),
        mlp=MLPConfig(epochs=50),
    ),
)
