"""The platform drive (docs/world.md, The platform drive) through the real env: how closely the
platform follows its reference, where its servo targets sit, and the calibrated position drive as the
low-pass filter of its gains (fast: few envs, <= 3 s).

Every test builds a `MovingPlatformEnv`, feeds its own references through
`env._next_trajectories` (so that a reset after a fall replays the same reference from t = 0),
steps with a = 0 (the robot stands under its joint PD) and reads the platform from the raw
batch state (`env.sim.qpos/qvel`).

Measured values (seeds below; 2 threads) behind the documented bounds:
- tracking, max |q_plf - ref| over the first 3 s of N = 5 train trajectories (8 envs, seed 0;
  the servo target ramps to the next reference within each policy step):
  kp 1 / kd 0.025: x, y, z 2.2, 2.3, 9.5 mm, yaw, pitch, roll 5.0, 2.5, 3.8 mrad;
  kp 0.5 / kd 0.01: 5.1, 5.2, 22.8 mm, 12.0, 3.8, 3.7 mrad;
  kp 2 / kd 0.04: 1.1, 1.3, 4.6 mm, 2.4, 0.8, 0.9 mrad.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from testkit import policy_steps as _steps
from testkit import replaying_env as _make_env

from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.scene import POSE_TO_JOINT, platform_gains

T_CHECK_S = 3.0  # horizon of every test


# (kp factor, kd factor, bound translation m, bound rotation rad)
TRACKING_CASES = [
    pytest.param(1.0, 0.025, 0.020, 0.012, id="nominal"),
    pytest.param(0.5, 0.01, 0.035, 0.025, id="test-soft"),
    pytest.param(2.0, 0.04, 0.035, 0.025, id="test-stiff"),
]


@pytest.mark.parametrize("kp_f, kd_f, bound_m, bound_rad", TRACKING_CASES)
def test_tracking_error_of_generated_reference(kp_f, kd_f, bound_m, bound_rad):
    n = 8
    refs = trj.sample(n, trj.TRAIN_RANGES, np.random.default_rng(100), n_waypoints=5)
    if kp_f == 1.0 and kd_f == 0.025:
        cfg = {"domain_rand": {"enabled": False}}  # the nominal factors
    else:  # degenerate test ranges: every reset draws exactly these factors
        cfg = {
            "domain_rand": {
                "split": "test",
                "test": {"platform_kp_factor": [kp_f, kp_f], "platform_kd_factor": [kd_f, kd_f]},
            }
        }
    env = _make_env(n, refs, **cfg)
    # the factors reached the batch's actuators
    gains = platform_gains(env.cfg.platform)
    np.testing.assert_allclose(env.intrinsics.platform_kp_factor, kp_f)
    np.testing.assert_allclose(env.intrinsics.platform_kd_factor, kd_f)
    gainprm = env.sim.expand("actuator_gainprm").numpy()
    plf_act_pos, plf_act_vel = env.plf_act_pos.numpy(), env.plf_act_vel.numpy()
    np.testing.assert_allclose(gainprm[:, plf_act_pos, 0], np.broadcast_to(gains.kp * kp_f, (n, 6)))
    np.testing.assert_allclose(gainprm[:, plf_act_vel, 0], np.broadcast_to(gains.kd * kd_f, (n, 6)))

    err_max = np.zeros(6)  # PLATFORM_JOINTS order: x, y, z, yaw, pitch, roll
    samples = 0
    a = torch.zeros(n, 12)
    for _ in range(_steps(env, T_CHECK_S)):
        env.step(a)
        # episode time of every env (0 for envs just reset, where platform and reference are 0)
        t = env.episode_length_buf.numpy() * env.dt_s
        live = t > 0
        ref = env.traj.evaluate(t)[0][:, POSE_TO_JOINT]
        err = np.abs(env.sim.qpos[:, env.index.plf_qpos].numpy() - ref)[live]
        samples += int(live.sum())
        err_max = np.maximum(err_max, err.max(axis=0, initial=0.0))
    trans, rot = err_max[:3].max(), err_max[3:].max()
    msg = (
        f"kp {kp_f} kd {kd_f}: max |error| x,y,z = {np.round(err_max[:3] * 1e3, 2)} mm, "
        f"yaw,pitch,roll = {np.round(err_max[3:] * 1e3, 2)} mrad over {samples} env-steps"
    )
    print(msg)
    assert samples >= 0.9 * n * _steps(env, T_CHECK_S), msg
    assert trans < bound_m, f"translation error above {bound_m * 1e3:.0f} mm: {msg}"
    assert rot < bound_rad, f"rotation error above {bound_rad * 1e3:.0f} mrad: {msg}"
    # closely but not perfectly (docs/world.md, The platform drive): a zero error would mean the test reads the reference
    assert trans > 1e-4 and rot > 1e-5, f"suspiciously perfect tracking: {msg}"


def test_servo_targets_sit_on_the_reference_at_every_policy_step():
    # the env never writes the targets (`act`): a reset zeroes them, where every trajectory starts,
    # and within each step they ramp to the next reference sample, so they must land on x_ref(t)
    # at every step boundary, up to rounding
    n = 4
    refs = trj.sample(n, trj.TRAIN_RANGES, np.random.default_rng(7), n_waypoints=6)
    env = _make_env(n, refs, platform={}, domain_rand={"enabled": False})
    act_adr = env.plf_act_adr.numpy()

    def target_error() -> float:
        t = env.episode_length_buf.numpy() * env.dt_s
        ref = env.traj.evaluate(t)[0][:, POSE_TO_JOINT]
        return float(np.abs(env.sim.act.numpy()[:, act_adr] - ref).max())

    assert target_error() == 0.0  # at reset
    moved = 0.0
    for _ in range(_steps(env, 2.0)):
        env.step(torch.zeros(n, 12))
        assert target_error() < 1e-12
        moved = max(moved, float(np.abs(env.sim.act.numpy()[:, act_adr]).max()))
    assert moved > 0.05, "the references barely moved: the check above would be empty"


@pytest.mark.parametrize(
    "kp_f, kd_f", [(1.0, 0.025), (0.5, 0.01), (2.0, 0.04)], ids=["nominal", "test-soft", "test-stiff"]
)
def test_position_drive_is_the_filter_of_its_gains(kp_f, kd_f):
    """The calibrated platform (no velocity feedforward) moves as M x'' = kp (x_ref - x) - kd x' per
    translational axis: a 2nd-order low-pass filter of the reference, far from tracking it."""
    from scipy import signal

    n, t_end = 2, 6.0
    t = np.arange(0.0, t_end + 1.0, 0.05)
    poses = np.zeros((n, len(t), 6))  # x, y, z = A (1 - cos 2 pi f t): from rest, a robot can stand on it
    for j, (amp_m, f_hz) in enumerate([(0.4, 0.25), (0.3, 0.35), (0.8, 0.2)]):
        poses[:, :, j] = amp_m * (1.0 - np.cos(2 * np.pi * f_hz * t * np.array([[1.0], [1.3]])))
    refs = trj.from_samples(t, poses)
    cfg = {
        "domain_rand": {
            "split": "test",
            "test": {"platform_kp_factor": [kp_f, kp_f], "platform_kd_factor": [kd_f, kd_f]},
        }
    }
    env = _make_env(n, refs, platform={}, **cfg)  # the default (calibrated) platform
    assert not env.cfg.platform.velocity_feedforward
    gains = platform_gains(env.cfg.platform)
    x_sim = [env.sim.qpos[:, env.index.plf_qpos[:3]].numpy().copy()]
    a = torch.zeros(n, 12)
    steps = _steps(env, t_end)
    for _ in range(steps):
        env.step(a)
        assert env.episode_length_buf.min() > 0, "an env reset: the comparison needs whole episodes"
        x_sim.append(env.sim.qpos[:, env.index.plf_qpos[:3]].numpy().copy())
    x_sim = np.array(x_sim)  # (steps + 1, n, 3)
    t_fine = np.arange(0.0, t_end + 1e-9, env.cfg.sim.dt_s)
    t_pol = np.arange(steps + 1) * env.dt_s
    m = env.cfg.platform.mass_kg
    worst = 0.0
    for j in range(3):
        kp, kd = gains.kp[j] * kp_f, gains.kd[j] * kd_f
        filt = signal.lti([kp], [m, kd, kp])
        for r in range(n):
            ref = refs.evaluate(t_fine, np.full(len(t_fine), r))[0][:, j]
            _, x_model, _ = signal.lsim(filt, ref, t_fine)
            model = np.interp(t_pol, t_fine, x_model)
            scale = np.abs(ref).max()
            err = np.abs(x_sim[:, r, j] - model).max()
            worst = max(worst, err / scale)
            # a real filter, not tracking: the platform lags its reference by a lot
            assert np.abs(x_sim[:, r, j] - np.interp(t_pol, t_fine, ref)).max() > 0.05 * scale
    assert worst < 0.03, (
        f"platform differs from the 2nd-order model by {worst:.1%} of the reference's amplitude"
    )
