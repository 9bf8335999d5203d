"""Fish (dm_control's fish facts; control step 0.04 s = 10 x 0.004 s).

x = [root position (3), root quaternion (w, x, y, z), fin and tail joints, velocities].

This project's own model, written from those facts: its bodies, gains and damping are not
dm_control's ``suite/fish.xml`` (nor D2C 2.0's ``fish_old.xml``, the same fish at 0.005 s),
and it swims far slower: D2C 2.0's stored optima, which bring its fish to the target, leave
this one near its start (``benchmarks/d2c20_fish.py``).
"""

from __future__ import annotations

import numpy as np

from mjx_surrogate.systems.spec import SystemDefaults
from mjx_surrogate.tasks import TaskPreset, state


def xml() -> str:
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


def default_config() -> SystemDefaults:
    # dm_control control step 0.04 s = 10 physics steps of 0.004 s; native wins on 2 cores.
    return SystemDefaults(xml, substeps=10, backend="native")


def _fish_d2c(nq, nv, nu):
    x0 = state(nq, nv, q3=1.0)
    goal = state(nq, nv, q1=0.4, q2=0.2, q3=1.0)
    w = np.zeros(nq + nv)
    w[:3] = 1.0
    return dict(T=600, x0=x0, x_goal=goal, Q=9 * np.diag(w), Q_f=1500 * np.diag(w), R=0.1 * np.eye(nu))


TASKS = {
    "fish_d2c": TaskPreset("fish", _fish_d2c, "D2C 2.0: rest -> (0, 0.4, 0.2), quaternion w = 1, T 600"),
}
