"""Physics backends: one batch of simulations of one `mujoco.MjModel`, behind one contract.

`make_backend(name, model, num_envs, sim_cfg, device)` returns the backend `name` (`env.backend`):

- ``cpu`` (default): `mujoco.batch.Batch` on a C thread pool (`backends/cpu.py`), float64;
- ``warp``: MuJoCo Warp on a CUDA device, or on Warp's CPU device for tests (`backends/warp.py`),
  float32; needs ``pip install -e ".[gpu]"``.

The contract (what the envs use; every array is a torch tensor on `device`, leading dim num_envs):

    model          the host `mujoco.MjModel` (names, sizes, qpos0); never modified
    num_envs, device, dtype
    qpos (n, nq), qvel (n, nv), ctrl (n, nu), act (n, na)
                   live views of the state, writable (a write is seen by the next step)
    sensordata (n, nsensordata), site_xpos (n, nsite, 3), actuator_force (n, nu)
                   live views, read-only. After `step` and `reset`, positions, velocities, site
                   positions and position/velocity sensors describe the current state; acceleration
                   quantities (accelerometer, contact sensors, actuator_force) the last substep
    expand(name)   (n, ...) live writable per-env values of a model field (domain randomization:
                   body_mass, body_ipos, geom_friction, actuator_gainprm, actuator_biasprm); the
                   derived constants follow at the next `reset(..., set_const=True)`
    step(nstep, ids=None) -> faulted
                   advance every env (or only envs `ids`, a long tensor; the others keep their state
                   exactly) nstep physics steps; returns the (n,) bool mask of envs that faulted
                   (a MuJoCo error or warning, non-finite state); only those need a reset
    reset(ids, qpos, qvel, ctrl, set_const)
                   fresh data for envs `ids` at the given state (rows in `ids` order), derived
                   quantities computed; `set_const` after writing per-env masses or CoMs
    forward(ids=None)
                   recompute the derived quantities of envs `ids` (all if None) after a write to
                   their state (e.g. a push added to qvel)
    get_state() / set_state(d)
                   everything an exact resume needs (integration state and per-env model fields)
    step_time_s, env_steps
                   wall time spent in the physics, and env-steps simulated (benchmarks)
"""

from __future__ import annotations

import mujoco
import torch

from lasmp.config.base import BACKENDS  # the one list, checked by the config (env.backend)


def make_backend(
    name: str, model: mujoco.MjModel, num_envs: int, sim_cfg, device: torch.device | str = "cpu"
):
    """The physics backend `name` for `num_envs` copies of `model` (`sim_cfg`: an `env.sim` config),
    its tensors on `device`."""
    device = torch.device(device)
    if name == "cpu":
        if device.type != "cpu":
            raise ValueError(
                f"env.backend=cpu keeps its state on the CPU; got device={device}. "
                "Use env.backend=warp for a CUDA device."
            )
        from lasmp.envs.backends.cpu import CpuBatchSim

        return CpuBatchSim(model, num_envs, sim_cfg.num_threads)
    if name == "warp":
        from lasmp.envs.backends.warp import WarpSim

        return WarpSim(model, num_envs, sim_cfg, device)
    raise ValueError(f"env.backend must be one of {BACKENDS}, got {name!r}")
