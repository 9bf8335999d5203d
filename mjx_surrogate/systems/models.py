"""The project's own MJCF models of the paper's systems.

Written from the physical facts in the dm_control suite and the D2C 2.0 setting
(see ``shared/reference.md``): masses, lengths, timesteps, gears and fluid density.
State convention everywhere: x = [qpos, qvel]. Controls are *not* clamped by the
models (``ctrllimited="false"``, as in D2C 2.0); box limits belong to the solver.
"""

from __future__ import annotations


def pendulum_xml() -> str:
    """Torque-driven pendulum, theta = 0 upright; 1 kg tip at 0.5 m, damping 0.1."""
    return """<mujoco model="pendulum">
  <option timestep="0.02" integrator="Euler" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="pole" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0"
            contype="0" conaffinity="0"/>
      <geom name="tip" type="sphere" pos="0 0 0.5" size="0.05" mass="1"
            contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="torque" joint="hinge" gear="1" ctrllimited="false"/>
  </actuator>
</mujoco>
"""


def cartpole_xml() -> str:
    """Cart on an unlimited rail with a 1 m, 0.1 kg pole; theta = 0 upright; RK4, dt 0.01."""
    return """<mujoco model="cartpole">
  <option timestep="0.01" integrator="RK4" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="cart" pos="0 0 1">
      <joint name="slider" type="slide" axis="1 0 0" damping="0"/>
      <geom name="cart" type="box" size="0.2 0.15 0.1" mass="1"
            contype="0" conaffinity="0"/>
      <body name="pole" pos="0 0 0">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0"/>
        <geom name="pole" type="capsule" fromto="0 0 0 0 0 1" size="0.045" mass="0.1"
              contype="0" conaffinity="0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="force" joint="slider" gear="10" ctrllimited="false"/>
  </actuator>
</mujoco>
"""


def fish_xml() -> str:
    """Free-floating fish in water (density 5000, no gravity, inertia-box fluid model).

    Free joint + 7 hinges (nq 14, nv 13, nx 27), 5 position actuators, two of them on
    fixed tendons (the tail bend and the symmetric fin flap).
    """
    return """<mujoco model="fish">
  <option timestep="0.004" integrator="Euler" gravity="0 0 0" density="5000" viscosity="0"/>
  <default>
    <geom contype="0" conaffinity="0" density="1000"/>
    <joint type="hinge" damping="0.0005" armature="0.0001"/>
    <position kp="0.0005" ctrllimited="false"/>
  </default>
  <worldbody>
    <body name="torso" pos="0 0 0">
      <freejoint name="root"/>
      <geom name="torso" type="ellipsoid" size="0.02 0.08 0.04"/>
      <body name="tail1" pos="0 -0.08 0">
        <joint name="tail1" axis="0 0 1"/>
        <geom name="tail1" type="ellipsoid" size="0.01 0.03 0.02" pos="0 -0.03 0"/>
        <body name="tail2" pos="0 -0.06 0">
          <joint name="tail2" axis="0 0 1"/>
          <joint name="tail_twist" axis="0 1 0"/>
          <geom name="tail_fin" type="ellipsoid" size="0.002 0.04 0.03" pos="0 -0.04 0"/>
        </body>
      </body>
      <body name="finright" pos="0.02 0.02 0">
        <joint name="finright_roll" axis="0 1 0"/>
        <joint name="finright_pitch" axis="1 0 0"/>
        <geom name="finright" type="ellipsoid" size="0.03 0.015 0.002" pos="0.03 0 0"/>
      </body>
      <body name="finleft" pos="-0.02 0.02 0">
        <joint name="finleft_roll" axis="0 1 0"/>
        <joint name="finleft_pitch" axis="1 0 0"/>
        <geom name="finleft" type="ellipsoid" size="0.03 0.015 0.002" pos="-0.03 0 0"/>
      </body>
    </body>
  </worldbody>
  <tendon>
    <fixed name="tail_bend">
      <joint joint="tail1" coef="0.5"/>
      <joint joint="tail2" coef="0.5"/>
    </fixed>
    <fixed name="fins_flap">
      <joint joint="finleft_roll" coef="0.5"/>
      <joint joint="finright_roll" coef="-0.5"/>
    </fixed>
  </tendon>
  <actuator>
    <position name="tail" tendon="tail_bend"/>
    <position name="tail_twist" joint="tail_twist"/>
    <position name="fins_flap" tendon="fins_flap"/>
    <position name="finleft_pitch" joint="finleft_pitch"/>
    <position name="finright_pitch" joint="finright_pitch"/>
  </actuator>
</mujoco>
"""


def swimmer_xml(n_links: int, joint_limits: bool = True) -> str:
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
