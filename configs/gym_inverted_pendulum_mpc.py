"""Closed loop on a model we did not write: gymnasium's inverted pendulum MJCF, as the
gymnasium package ships it (``pip install gymnasium``; the file is found in the installed
package, never copied here), with its own time step (0.02 s), damping, joint limits and
control range (+-3). Task: from the pole tilted by 0.2 rad, bring it upright with the
cart at the centre in 2 s (100 steps). Every controller replans over 30 steps at 25 Hz
(every 2nd step of the 50 Hz plant, which runs the last plan with its gains between), on
the model and on a 1.5x heavier plant, under process noise, the SINDy models also
refitted online; the oracle is central differences (jacfwd through this model compiles
for minutes on 2 cores). D2C-MPC's replans identify by forward differences with at most
2 iterations of 4 step sizes. Replanning at every step costs the same to 1.6 % (median,
every condition) at twice the simulations: 660 black-box steps per control step, 1.6-2.0x
real time on 2 cores, against 330 and 3.2-3.6x (docs/mpc.md). The sampling planners run
at their own settings searched on this task (predictive sampling and MPPI 512 samples of
spread 0.3, CEM 256 of 0.3, in control units), each beside its row at D2C-MPC's budget."""

import importlib.util
import os

from mjx_surrogate.runs.config import (
    Config,
    ExperimentConfig,
    MPCConfig,
    MPCSysIdConfig,
    SystemConfig,
    TaskConfig,
)


def _asset(name: str) -> str:
    """The path of one of gymnasium's MuJoCo assets, or a path that says how to get it
    (the run then stops on it with a one-line error naming system.mjcf_path)."""
    spec = importlib.util.find_spec("gymnasium")
    root = (
        os.path.dirname(spec.origin)
        if spec and spec.origin
        else "<gymnasium is not installed: pip install gymnasium>"
    )
    return os.path.join(root, "envs", "mujoco", "assets", name)


# the sampling planners' spread in control units, as docs/mpc.md's tables were measured
CONTROL_UNITS = {f"mpc.{p}": {"sigma_units": "control"} for p in ("predictive_sampling", "mppi", "cem")}

CONFIG = Config(
    system=SystemConfig(name="mjcf", mjcf_path=_asset("inverted_pendulum.xml"), backend="native"),
    task=TaskConfig(
        preset="custom",
        T=100,
        x0=(0.0, 0.2, 0.0, 0.0),
        x_goal=(0.0, 0.0, 0.0, 0.0),
        Q_diag=(1.0, 1.0, 0.01, 0.01),
        Q_f_diag=(10.0, 10.0, 0.1, 0.1),
        R_diag=(0.01,),
    ),
    experiment=ExperimentConfig(kind="mpc", x64=True, exact_oracle=True, oracle="finite_difference"),
    mpc=MPCConfig(
        horizon=30,
        steps=100,
        max_iter=2,
        n_alphas=4,
        sysid=MPCSysIdConfig(scheme="forward_difference"),
        replan_hz=25.0,
        horizon_end="receding",  # every plan H ahead, as measured in docs/mpc.md
        process_noise=(0.0, 0.01, 0.03),
        plants=("model", "mass=1.5"),
        n_episodes=4,
        refit_weight=10.0,
    ),
    # the sampling planners at their own settings searched on this task (docs/mpc.md), each
    # beside its row at D2C-MPC's budget, in control units
    extensions={
        f"mpc.{p}": {"sigma_units": "control", "sigma": 0.3, "budget_row": True, "samples": S}
        for p, S in (("predictive_sampling", 512), ("mppi", 512), ("cem", 256))
    },
)
