"""N-link swimmer (dm_control's swimmer facts; control step 0.03 s = 15 x 0.002 s).

Registered as ``swimmer<N>`` for any N >= 2. The root body's origin is the nose, so
qpos[0:2] is the nose position in the plane.
"""

from __future__ import annotations

import numpy as np

from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.tasks import TaskPreset, state


def xml(n_links: int, joint_limits: bool = True) -> str:
    """Planar n-link swimmer in a viscous-free dense fluid (density 3000, inertia box).

    The root body's origin is the nose, so qpos[0:2] is the nose position in the plane.
    Joints: rootx, rooty (slide), rootz (hinge), then n-1 hinges limited to +-360/n deg.
    nq = nv = n + 2, nu = n - 1.
    """
    if not isinstance(n_links, int) or n_links < 2:
        raise ValueError(f"system.n_links: must be an integer >= 2, got {n_links!r}")
    seg = 0.1
    limit = 360.0 / n_links
    lim = f'limited="true" range="{-limit:.6g} {limit:.6g}"' if joint_limits else 'limited="false"'

    def link(i: int) -> str:
        if i == n_links:
            return ""
        inner = link(i + 1)
        return (
            f'<body name="seg{i}" pos="{-seg} 0 0">\n'
            f'  <joint name="joint{i}" type="hinge" axis="0 0 1" {lim}/>\n'
            f'  <geom name="seg{i}" type="capsule" fromto="0 0 0 {-seg} 0 0" size="0.01"/>\n'
            f"  {inner}\n</body>"
        )

    motors = "\n    ".join(
        f'<motor name="motor{i}" joint="joint{i}" gear="5e-4" ctrllimited="false"/>'
        for i in range(1, n_links)
    )
    return f"""<mujoco model="swimmer{n_links}">
  <option timestep="0.002" integrator="Euler" gravity="0 0 0" density="3000" viscosity="0"/>
  <default>
    <geom contype="0" conaffinity="0" density="1000"/>
    <joint damping="1e-4" armature="1e-4" solreflimit="0.05 1"/>
  </default>
  <worldbody>
    <body name="head" pos="0 0 0">
      <joint name="rootx" type="slide" axis="1 0 0"/>
      <joint name="rooty" type="slide" axis="0 1 0"/>
      <joint name="rootz" type="hinge" axis="0 0 1"/>
      <geom name="head" type="capsule" fromto="0 0 0 {-seg} 0 0" size="0.01"/>
      {link(1)}
    </body>
  </worldbody>
  <actuator>
    {motors}
  </actuator>
</mujoco>
"""


def default_config(n_links: int) -> SystemDefaults:
    # dm_control control step 0.03 s = 15 physics steps of 0.002 s; native wins on 2 cores.
    return SystemDefaults(lambda: xml(n_links), substeps=15, backend="native")


def _swimmer_nose(T):
    def build(nq, nv, nu):
        w = np.zeros(nq + nv)
        w[:2] = 1.0  # the root body's origin is the nose: qpos[0:2]
        return dict(
            T=T,
            x0=state(nq, nv),
            x_goal=state(nq, nv, q0=0.5, q1=-0.6),
            Q=10 * np.diag(w),
            Q_f=1000 * np.diag(w),
            R=0.01 * np.eye(nu),
        )

    return build


TASKS = {
    "swimmer3_d2c": TaskPreset("swimmer3", _swimmer_nose(900), "D2C 2.0: nose -> (0.5, -0.6), T 900"),
    "swimmer6_d2c": TaskPreset("swimmer6", _swimmer_nose(800), "D2C 2.0: nose -> (0.5, -0.6), T 800"),
    "swimmer_nose": TaskPreset("swimmer*", _swimmer_nose(300), "any swimmerN: nose -> (0.5, -0.6), T 300"),
}
