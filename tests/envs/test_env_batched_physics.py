"""The batched moving-platform env's physics: domain randomization written per env into the model
the physics uses, determinism under a seed, and equality with a serial mj_step loop."""

from __future__ import annotations

import mujoco
import numpy as np
import torch
from testkit import platform_env as make
from testkit import static_platform

from lasmp.envs.moving_platform.domain_rand import nominal_intrinsics
from lasmp.robots import a1


def test_domain_randomization_writes_per_env_model_parameters_within_ranges():
    for split, lo_mass, hi_mass in (("train", 4.0, 5.0), ("test", 3.5, 5.5)):
        env = make(64, domain_rand={"split": split})
        p = env.intrinsics
        assert lo_mass <= p.trunk_mass_kg.min() and p.trunk_mass_kg.max() <= hi_mass
        assert p.trunk_mass_kg.std() > 0.1
        trunk = env.sim.model.body("trunk").id
        assert np.allclose(env.sim.batch.expanded("body_mass")[:, trunk], p.trunk_mass_kg)
        ipos = env.sim.batch.expanded("body_ipos")[:, trunk]
        assert np.allclose(ipos - env.sim.model.body_ipos[trunk], p.com_shift_m)
        act = env.sim.model.actuator("FL_thigh_joint").id
        j = a1.JOINT_NAMES.index("FL_thigh_joint")
        assert np.allclose(env.sim.batch.expanded("actuator_gainprm")[:, act, 0], p.joint_kp[:, j])
        assert np.allclose(env.sim.batch.expanded("actuator_biasprm")[:, act, 2], -p.joint_kd[:, j])
        foot = env.sim.model.geom("RR_foot").id
        assert np.allclose(env.sim.batch.expanded("geom_friction")[:, foot, 0], p.foot_friction)
        x_imp = env.get_observations()["priv_implicit"].double().numpy()
        assert np.allclose(x_imp[:, 0], p.trunk_mass_kg, atol=1e-5)
        assert np.allclose(x_imp[:, 5:17], p.joint_kp, atol=1e-4)


def test_randomized_joint_gains_change_the_dynamics():
    """The per-env Kp written through Batch.expand is the one the physics uses."""
    env = make(2, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    params = nominal_intrinsics(1, env.cfg.platform.kd_factor_ref)
    params.joint_kp[:] = 80.0
    env.writer.write(np.array([1]), params)
    for _ in range(50):
        env.step(torch.zeros(2, 12))
    h = env.readout.p_body_p[:, 2]
    assert h[1] > h[0] + 0.005, h  # stiffer joints sag less


def test_same_seed_gives_identical_observations_over_100_steps():
    def run(seed):
        env = make(8, seed=seed)
        gen = torch.Generator().manual_seed(0)
        out = []
        for _ in range(100):
            obs = env.step(0.3 * torch.randn(8, 12, generator=gen))[0]
            out.append(obs["critic"].clone())
        return torch.stack(out)

    a, b, c = run(3), run(3), run(4)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)


def test_batched_step_equals_a_serial_mj_step_loop():
    env = make(4)
    for _ in range(10):
        env.step(0.5 * torch.randn(4, 12))
    actions = torch.from_numpy(0.5 * np.random.default_rng(0).standard_normal((4, 12)))  # float64
    env._apply_actions(actions)  # ctrl and act set
    batch = env.sim.batch
    models = [batch.get_model(i) for i in range(4)]  # with each env's randomized parameters
    datas = [batch.get_data(i) for i in range(4)]  # state, controls and servo targets
    assert not env.sim.step(env.cfg.sim.decimation).any()
    for i in range(4):
        for _ in range(env.cfg.sim.decimation):
            mujoco.mj_step(models[i], datas[i])
        assert np.array_equal(datas[i].qpos, env.sim.qpos[i].numpy()), i
        assert np.array_equal(datas[i].qvel, env.sim.qvel[i].numpy()), i
