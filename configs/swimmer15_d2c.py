"""The 15-link swimmer of the paper's first figure: nose -> (0.5, -0.6) in 8 s (T 800 at 0.01 s, as
D2C 2.0 ran swimmer6), with swimmer6_d2c's solver settings except the identification design.
nx 34, nu 14: central differences with an orthogonal design of exactly nx + nu = 48
perturbations per time step (the fewest that determine [A_t B_t], perfectly conditioned),
float64 and sigma 1e-5 as for swimmer6, on the native backend (MJX walks a 15-link chain
level by level and is far slower on CPU cores: docs/performance.md). From 5 random starts
(one after another on native MuJoCo, about 11 min on 2 cores), the cheapest kept: whether D2C
converges here depends on the start and on the machine's rounding (one start converged at
2011.4 on one machine, stalled at 1873.3 on another), so the report judges all five.
"""

import dataclasses

from configs.swimmer6_d2c import CONFIG as SWIMMER6
from mjx_surrogate.runs.config import SystemConfig, TaskConfig

CONFIG = dataclasses.replace(
    SWIMMER6,
    system=SystemConfig(name="swimmer15", timestep=0.01, substeps=1, backend="native"),
    task=TaskConfig(preset="swimmer_nose", T=800),
    solver=dataclasses.replace(SWIMMER6.solver, max_iter=400, rel_tol=1e-5, n_starts=5),
    sysid=dataclasses.replace(SWIMMER6.sysid, design="orthogonal", n_samples=48),
)
