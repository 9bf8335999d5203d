"""experiments.inspect: a model's state map, actuators, sensors and mocap, as data and text."""

import json

import mujoco
import numpy as np

from mjx_surrogate.systems.inspection import describe, render

MODEL = """
<mujoco>
  <worldbody>
    <body name="target" mocap="true" pos="0.5 0 1"><geom type="sphere" size="0.02" contype="0"/></body>
    <body name="arm" pos="0 0 1">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <site name="tip" pos="0.3 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="servo" joint="shoulder" kp="200" ctrlrange="-3 3" forcerange="-50 50"/>
    <velocity name="spin" joint="elbow" kv="5"/>
    <motor name="push" joint="elbow" gear="7"/>
  </actuator>
  <sensor><jointpos joint="elbow"/><framepos objtype="site" objname="tip"/></sensor>
</mujoco>
"""


def test_describe_names_actuator_kinds_limits_sensors_and_mocap():
    m = mujoco.MjModel.from_xml_string(MODEL)
    info = describe(m, check_mjx=False)
    servo, spin, push = info["actuators"]
    assert (servo["kind"], servo["drives"], servo["forcerange"]) == (
        "position servo",
        "joint shoulder",
        [-50, 50],
    )
    assert servo["ctrlrange"] == [-3, 3] and servo["limited"]
    assert (spin["kind"], spin["drives"]) == ("velocity servo", "joint elbow")
    assert (push["kind"], push["gear"], push["limited"]) == ("motor", 7.0, False)
    assert np.isinf(push["forcerange"]).all()
    assert [(s["type"], s["dim"]) for s in info["sensors"]] == [("jointpos", 1), ("framepos", 3)]
    assert info["mocap_bodies"] == ["target"] and info["nx"] == 4 and info["nu"] == 3
    text = render(info)
    assert (
        "u[0] servo: position servo on joint shoulder, gear 1, ctrlrange [-3, 3], force within [-50, 50]"
        in text
    )
    assert "u[2] push: motor on joint elbow, gear 7, unlimited" in text
    assert "mocap bodies (positioned by the user" in text and "target" in text
    assert "framepos, 3" in text


def test_a_model_without_actuators_says_so_on_the_command_line(tmp_path, capsys):
    from experiments import inspect

    path = tmp_path / "passive.xml"
    path.write_text(MODEL.split("<actuator>")[0] + "</mujoco>")
    assert inspect.main([str(path)]) == 0
    assert "actuators: none (nothing for a controller to drive)" in capsys.readouterr().out
    assert inspect.main([str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mocap_bodies"] == ["target"]
    assert inspect.main([str(tmp_path / "missing.xml")]) == 2
