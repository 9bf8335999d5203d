"""mjx_surrogate: batched data-driven nonlinear optimal control on MuJoCo with JAX.

The public API, importable from here. Importing changes no global state; call
:func:`configure_runtime` once before the first computation (the CLI does).

    import mjx_surrogate as ms
    ms.configure_runtime()
    cfg, system, task = ms.resolve(ms.Config(system=ms.SystemConfig(name="pendulum")))
    result = ms.solve_d2c(system, task, U0, jax.random.key(0))
    timed = ms.chunked.solve(system, task, U0, jax.random.key(0))  # host-driven, cacheable
    sol = ms.solve_config(ms.resolve(cfg))  # exactly the command line's D2C solve: sol.timed.out
"""

from mjx_surrogate import progress
from mjx_surrogate.control import chunked, mpc
from mjx_surrogate.control.d2c import solve_d2c, solve_exact, solve_multistart
from mjx_surrogate.control.ilqr import ILQRParams, ILQRResult, StopReason, ilqr
from mjx_surrogate.control.mpc import MPCResult, receding_horizon
from mjx_surrogate.cost import Cost
from mjx_surrogate.errors import ConfigError
from mjx_surrogate.identification.sysid import IdentificationScheme, SysIdParams, register_scheme
from mjx_surrogate.runs.config import (
    AnalysisConfig,
    Config,
    DataConfig,
    ExperimentConfig,
    MLPConfig,
    MPCConfig,
    MPCSysIdConfig,
    SindyConfig,
    SolverConfig,
    SurrogateConfig,
    SysIdConfig,
    SystemConfig,
    TaskConfig,
)
from mjx_surrogate.runs.experiment_kinds import ExperimentKind, register_experiment
from mjx_surrogate.runs.extension_settings import settings_of
from mjx_surrogate.runs.pipeline import solve_config, start_controls
from mjx_surrogate.runs.resolution import mpc_params, resolve, solver_params
from mjx_surrogate.runtime import configure_runtime
from mjx_surrogate.surrogates import FitContext, Fitted, SurrogateKind, fit_all, register_surrogate
from mjx_surrogate.systems import System, from_mjcf, make_system, register_system
from mjx_surrogate.tasks import Task, make_task

__version__ = "0.5.0"

__all__ = [
    "AnalysisConfig",
    "MPCConfig",
    "MPCSysIdConfig",
    "Config",
    "ConfigError",
    "Cost",
    "DataConfig",
    "ExperimentConfig",
    "ExperimentKind",
    "FitContext",
    "Fitted",
    "ILQRParams",
    "ILQRResult",
    "MPCResult",
    "IdentificationScheme",
    "MLPConfig",
    "SindyConfig",
    "SolverConfig",
    "StopReason",
    "SurrogateConfig",
    "SurrogateKind",
    "SysIdConfig",
    "SysIdParams",
    "System",
    "SystemConfig",
    "Task",
    "TaskConfig",
    "configure_runtime",
    "fit_all",
    "from_mjcf",
    "ilqr",
    "make_system",
    "make_task",
    "chunked",
    "mpc",
    "progress",
    "receding_horizon",
    "register_experiment",
    "register_scheme",
    "register_surrogate",
    "register_system",
    "resolve",
    "settings_of",
    "solve_d2c",
    "solve_exact",
    "solve_multistart",
    "solve_config",
    "start_controls",
    "solver_params",
    "mpc_params",
]
