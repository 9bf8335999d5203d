"""mjx_surrogate/systems/plant.py: MPC plants that differ from the model, checked against
models written that way (MJCF text), closed-form scaling laws on a model we did not write,
a fixed point that moves with a function black box's parameter, and an episode on it."""

import json

import mujoco
import numpy as np
import pytest

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.systems import lorenz, pendulum
from mjx_surrogate.systems.plant import changed_model, check_plant, function_plant, parse_plant, plant_label

# the pendulum's MJCF with one quantity written otherwise: the independent reference per change
EDITS = {
    "mass=1.5": [('size="0.05" mass="1"', 'size="0.05" mass="1.5"')],
    "damping=2": [('damping="0.1"', 'damping="0.2"')],
    "gravity=1.1": [('gravity="0 0 -9.81"', 'gravity="0 0 -10.791"')],
    "length=1.2": [
        ('pos="0 0 1"', 'pos="0 0 1.2"'),
        ('fromto="0 0 0 0 0 0.5" size="0.02"', 'fromto="0 0 0 0 0 0.6" size="0.024"'),
        ('pos="0 0 0.5" size="0.05"', 'pos="0 0 0.6" size="0.06"'),
    ],
}


def _trajectory(model: mujoco.MjModel, steps: int = 200) -> np.ndarray:
    d = mujoco.MjData(model)
    d.qpos[:], d.qvel[:] = 2.0, -1.0
    out = []
    for t in range(steps):
        d.ctrl[:] = np.sin(0.1 * t)
        mujoco.mj_step(model, d)
        out.append(np.concatenate([d.qpos, d.qvel]))
    return np.array(out)


@pytest.mark.parametrize("text", [*EDITS, "mass=1.5,length=1.2,damping=2"])
def test_a_changed_pendulum_moves_as_the_pendulum_written_that_way(text):
    model = mujoco.MjModel.from_xml_string(pendulum.xml())
    xml = pendulum.xml()
    for change in text.split(","):
        for old, new in EDITS[change]:
            assert old in xml
            xml = xml.replace(old, new)
    written = mujoco.MjModel.from_xml_string(xml)
    changed = changed_model(model, parse_plant(text))
    for name in ("body_pos", "body_ipos", "body_mass", "body_inertia", "dof_damping", "jnt_pos"):
        np.testing.assert_allclose(getattr(changed, name), getattr(written, name), rtol=1e-12, err_msg=name)
    for name in ("geom_pos", "geom_size", "geom_rbound", "geom_aabb"):  # shapes: contacts, video
        np.testing.assert_allclose(getattr(changed, name), getattr(written, name), rtol=1e-12, err_msg=name)
    np.testing.assert_allclose(changed.opt.gravity, written.opt.gravity, rtol=1e-12)
    X = _trajectory(changed)
    np.testing.assert_allclose(X, _trajectory(written), rtol=1e-10, atol=1e-12)
    assert np.abs(X - _trajectory(model)).max() > 0.1  # a plant the controller does not know


def test_scaling_laws_on_a_model_we_did_not_write():
    """dm_control's walker, as downloaded (slide and hinge joints off their bodies' origins),
    at a bent pose: with masses x s the mass matrix and the gravity force scale by s; with
    lengths x s (masses kept) M_ij scales by d_i d_j and the gravity force by d_i, where d
    is s for a hinge and 1 for a slide (a slide's coordinate is not rescaled); armature apart."""
    from thirdparty import model_path

    path = model_path("dm_control", "walker.xml")
    if path is None:
        pytest.skip("dm_control's wheel could not be downloaded")
    model = mujoco.MjModel.from_xml_path(path)
    qpos = np.random.default_rng(0).uniform(-0.5, 0.5, model.nq)

    def M_and_gravity(m):
        d = mujoco.MjData(m)
        d.qpos[:] = qpos
        mujoco.mj_forward(m, d)  # qvel = 0: the bias force is gravity alone
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        return M - np.diag(m.dof_armature), d.qfrc_bias.copy()

    M0, g0 = M_and_gravity(model)
    M, g = M_and_gravity(changed_model(model, parse_plant("mass=1.3")))
    np.testing.assert_allclose(M, 1.3 * M0, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(g, 1.3 * g0, rtol=1e-10, atol=1e-12)
    hinge = model.jnt_type[model.dof_jntid] == mujoco.mjtJoint.mjJNT_HINGE
    assert hinge.any() and not hinge.all()
    d = np.where(hinge, 1.3, 1.0)
    M, g = M_and_gravity(changed_model(model, parse_plant("length=1.3")))
    np.testing.assert_allclose(M, np.outer(d, d) * M0, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(g, d * g0, rtol=1e-10, atol=1e-12)


def test_what_a_plant_cannot_change_is_refused_before_any_compile():
    mesh = (
        '<mujoco><asset><mesh name="m" vertex="0 0 0 1 0 0 0 1 0 0 0 1"/></asset><worldbody><body>'
        '<joint name="j" type="hinge"/><geom type="mesh" mesh="m"/></body></worldbody>'
        '<actuator><motor joint="j"/></actuator></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(mesh)
    with pytest.raises(ConfigError, match="mesh or height field"):
        changed_model(model, parse_plant("length=2"))
    with pytest.raises(ConfigError, match="no damping"):
        changed_model(model, parse_plant("damping=2"))
    changed_model(model, parse_plant("mass=2"))  # masses scale whatever the geoms
    assert plant_label(parse_plant(" model ")) == "model"
    assert plant_label(parse_plant("mass=1.50, length=2")) == "mass=1.5,length=2"


def test_a_function_black_box_plant_has_its_parameter_changed():
    """Lorenz with rho = 30: its fixed point C- = (-sqrt(beta (rho - 1)), same, rho - 1)
    moves with rho; the plant holds the new one with u = 0 and the model does not."""
    model = lorenz.make_system()
    plant = function_plant(model, lorenz.make_system, parse_plant("rho=30"), "rho=30")
    c = np.sqrt(lorenz.BETA * 29.0)
    fixed = np.array([-c, -c, 29.0])
    u = np.zeros(1)
    np.testing.assert_allclose(np.asarray(plant.step(fixed, u)), fixed, atol=1e-9)
    assert np.abs(np.asarray(model.step(fixed, u)) - fixed).max() > 1e-3
    assert plant.name == "lorenz[rho=30]"
    with pytest.raises(ConfigError, match="lorenz's parameters are dt, substeps, sigma, rho, beta"):
        check_plant(model, "g=3", lorenz.make_system)
    with pytest.raises(ConfigError, match="changes dt"):
        check_plant(model, "dt=0.02", lorenz.make_system)
    with pytest.raises(ConfigError, match="given built"):
        check_plant(model, "rho=30", model)


@pytest.mark.slow
def test_a_users_function_entry_builds_the_plant(tmp_path):
    """system.entry naming a function: the plant calls it with the plant's keywords."""
    from experiments import run as cli

    (tmp_path / "box.py").write_text(
        "import jax.numpy as jnp\n"
        "from mjx_surrogate.systems import from_jax\n"
        "def make(gain=1.0):\n"
        "    return from_jax(lambda x, u: 0.9 * x + 0.1 * gain * u, 1, 1, 0.1, name='box')\n"
    )
    argv = [
        "--system.name", "python", "--system.entry", f"{tmp_path / 'box.py'}:make", "--task.preset", "custom",
        "--task.x0", "1", "--task.x_goal", "0", "--task.Q_diag", "1", "--task.Q_f_diag", "10",
        "--task.T", "10", "--experiment.kind", "mpc",
        "--mpc.controllers", "d2c", "--mpc.plants", "gain=0.5", "--mpc.process_noise", "0",
        "--mpc.n_episodes", "1", "--mpc.horizon", "5", "--mpc.steps", "6", "--experiment.no_video",
        "--experiment.no_progress", "--out", str(tmp_path / "runs"),
    ]  # fmt: skip
    assert cli.main(["default", *argv]) == 0
    (path,) = (tmp_path / "runs").iterdir()
    m = json.loads((path / "metrics.json").read_text())
    (row,) = m["mpc_rows"]
    X, U = (np.load(path / "arrays.npz")[row["arrays"][k]][0] for k in "XU")
    assert row["plant"] == "gain=0.5"
    np.testing.assert_allclose(X[1:], 0.9 * X[:-1] + 0.05 * U, atol=1e-12)  # the plant's step
