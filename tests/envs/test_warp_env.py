"""The moving-platform env on the MuJoCo Warp backend (Warp's CPU device) against the CPU backend.

Marked `warp`: run with `pytest -m warp` after `pip install -e ".[gpu]"`. The env draws every
random quantity on the host with its numpy generator, so two envs of the same seed get the same
trajectories, robots (masses, CoMs, frictions, gains) and initial states whatever their backend;
only the physics differs (MuJoCo in float64 against MuJoCo Warp in float32).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

pytest.importorskip("mujoco_warp", reason="the gpu extra is not installed: pip install -e '.[gpu]'")

from lasmp.config.base import build_env_cfg  # noqa: E402
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg  # noqa: E402
from lasmp.envs.moving_platform.env import MovingPlatformEnv  # noqa: E402
from lasmp.eval import benchmark as bm  # noqa: E402
from lasmp.eval.build import eval_env_overrides  # noqa: E402
from lasmp.eval.run import run_benchmark  # noqa: E402

pytestmark = pytest.mark.warp
# the actions' sway: 0.1 (0.025 rad at the joints) moves the legs and shifts the feet's loads; at 0.3
# the feet start to lift and re-touch, and both backends' contact events amplify any difference
# (C MuJoCo at solver tolerance 1e-6 then ends 4 mm from itself at 1e-8)
AMPLITUDE = 0.1


def _env(backend: str, n: int, seed: int, **sim) -> MovingPlatformEnv:
    overrides = {"num_envs": n, "seed": seed, "backend": backend, "sim": {"num_threads": 1, **sim}}
    return MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg))


def _max_abs_per_env(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return (a.double() - b.double()).abs().flatten(1).max(dim=1).values


def test_both_backends_agree_over_100_policy_steps():
    """Same scene, initial states, randomization and controls through the whole env: positions,
    velocities and foot contacts agree over 100 policy steps (2 s). The actions are a fixed small
    sway, so the legs move and the feet's loads shift; the platform follows each env's own (randomized)
    trajectory with its own (randomized) PD gains.

    Tolerances, per env (max over the run): MuJoCo Warp runs in float32 and stops its solver at
    tolerance 1e-6, where C MuJoCo goes on to 1e-8. What that solver tolerance is worth here is
    measured, not guessed: a third env, C MuJoCo at tolerance 1e-6, shows how far C itself moves.
    Warp may differ from C by at most twice that, plus a float32 floor (1e-4 m or rad in qpos, 5e-3
    m/s or rad/s in qvel: rounding of ~1e-7 per substep, damped by the servos and contacts)."""
    n, steps = 4, 100
    cpu, loose, warp = _env("cpu", n, 3), _env("cpu", n, 3, solver_tolerance=1e-6), _env("warp", n, 3)
    assert warp.sim.dtype == torch.float32 and cpu.sim.dtype == torch.float64
    for env in (cpu, loose, warp):
        env.reset()
    # the same draws: the intrinsics written into both backends' per-env model fields
    for name in ("body_mass", "body_ipos", "geom_friction", "actuator_gainprm", "actuator_biasprm"):
        np.testing.assert_allclose(warp.sim.expand(name).numpy(), cpu.sim.expand(name).numpy(), rtol=1e-6)
    assert cpu.sim.expand("body_mass")[:, 1].unique().numel() == n  # and they differ between envs
    phase = torch.linspace(0, 2 * np.pi, 12)
    zeros = torch.zeros(n, dtype=torch.float64)
    err = {"qpos": zeros.clone(), "qvel": zeros.clone()}
    slack = {"qpos": zeros.clone(), "qvel": zeros.clone()}
    contact_agree = []
    for k in range(steps):
        a = AMPLITUDE * torch.sin(0.1 * k + phase).expand(n, 12)
        dones = [env.step(a)[2] for env in (cpu, loose, warp)]
        assert not any(d.any() for d in dones), "no env may end within 2 s of this sway"
        for key in err:
            err[key] = torch.maximum(
                err[key], _max_abs_per_env(getattr(warp.sim, key), getattr(cpu.sim, key))
            )
            slack[key] = torch.maximum(
                slack[key], _max_abs_per_env(getattr(loose.sim, key), getattr(cpu.sim, key))
            )
        contact_agree.append((warp.readout.foot_contact == cpu.readout.foot_contact).float().mean())
    print(f"warp vs C per env: {err}; C at tolerance 1e-6 vs 1e-8: {slack}")
    assert (err["qpos"] <= 1e-4 + 2 * slack["qpos"]).all(), (err, slack)
    assert (err["qvel"] <= 5e-3 + 2 * slack["qvel"]).all(), (err, slack)
    plf = [cpu.sim.model.joint(j).qposadr[0] for j in ("plf_x", "plf_y", "plf_z")]
    assert cpu.sim.qpos[:, plf].abs().max() > 0.01  # the platform did move
    # a foot at the edge of contact may touch a substep earlier on one backend
    assert float(torch.stack(contact_agree).mean()) > 0.97


def test_stand_still_collides_in_the_same_benchmark_episodes():
    """Stand Still (a = 0) on 16 benchmark episodes (a benchmark made as Xi_eval is, seed 0, 16
    trajectories and 16 robots of the testing ranges): the same episodes end in a collision on both
    backends."""
    bench = bm.generate(num_trajectories=16, num_robots=16, seed=0)
    outcomes = {}
    for backend, device in (("cpu", "cpu"), ("warp", "cpu")):
        overrides = {**eval_env_overrides(16, 0), "backend": backend, "sim": {"num_threads": 1}}
        env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg), device=device)
        out = run_benchmark(env, lambda obs: torch.zeros(16, 12), bench, 16, progress=False)
        outcomes[backend] = out["episodes"]["collision"]
    assert 0 < outcomes["cpu"].sum() < 16, (
        "the episodes must hold both outcomes for the test to mean anything"
    )
    np.testing.assert_array_equal(outcomes["warp"], outcomes["cpu"])
