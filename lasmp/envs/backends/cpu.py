"""CPU physics backend: all envs of one model on `mujoco.batch.Batch` (MuJoCo >= 4.0).

One call steps every simulation `nstep` substeps on a C thread pool (no Python loop over envs
or substeps). The batch is persistent (one MjData per env) so that the stage computed after a
step (`mjSTAGE_VEL`: positions, velocities and their sensors current at the new state) is
reused by the next step at no extra cost; acceleration-stage sensors (accelerometer, contact
sensors) then describe the last substep, 1 physics dt old.

The state and outputs are exposed as torch CPU tensors that view the Batch's own memory
(`torch.from_numpy`, no copies), float64, per the contract in `lasmp.envs.backends`.

Faults are data: `step` returns a boolean mask of simulations that raised a MuJoCo error,
raised a warning (e.g. a bad qacc that made MuJoCo reset the data itself) or hold non-finite
state. The caller terminates and resets those envs alone.
"""

from __future__ import annotations

import time

import mujoco
import mujoco.batch
import numpy as np
import torch

_STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_VEL)
_STAGE_NONE = int(mujoco.mjtStage.mjSTAGE_NONE)


class CpuBatchSim:
    device = torch.device("cpu")
    dtype = torch.float64

    def __init__(self, model: mujoco.MjModel, num_envs: int, num_threads: int = 0):
        self.model = model
        self.num_envs = num_envs
        self.batch = mujoco.batch.Batch(model, num_envs, nthread=num_threads, persistent=True)
        b = self.batch
        # live views: state rows (writable) and derived outputs (read-only, refreshed by every call)
        self.qpos = torch.from_numpy(b.bind("qpos"))
        self.qvel = torch.from_numpy(b.bind("qvel"))
        self.ctrl = torch.from_numpy(b.bind("ctrl"))
        self.act = torch.from_numpy(b.bind("act"))
        self.sensordata = _readonly_view(b.bind("sensordata"))
        self.site_xpos = _readonly_view(b.bind("site_xpos"))
        self.actuator_force = _readonly_view(b.bind("actuator_force"))
        self._warnings_seen = self._warning_count().copy()
        self._expanded: list[str] = []  # model fields given per-env values (domain randomization)
        self.step_time_s = 0.0  # wall time spent inside Batch.step, for benchmarks
        self.env_steps = 0  # policy steps simulated, summed over envs (fewer with `ids`), for benchmarks

    def _warning_count(self) -> np.ndarray:
        return self.batch.warning[:, :, 1].sum(axis=1)  # (nsim,) total warnings raised so far

    def expand(self, name: str) -> torch.Tensor:
        """Per-env values of a model field, (num_envs, ...), live."""
        if name not in self._expanded:
            self._expanded.append(name)
        return torch.from_numpy(self.batch.expand(name))

    def get_state(self) -> dict:
        """Everything a later `set_state` needs to continue bit for bit: each env's full integration
        state (positions, velocities, actuator states, controls, warm start, ...) and the per-env
        model fields."""
        return {
            "state": self.batch.state.copy(),
            "model": {name: np.array(self.batch.expand(name)) for name in self._expanded},
        }

    def set_state(self, saved: dict) -> None:
        """Restore `get_state` output: the model fields (and the constants derived from them), the
        integration state, and the position and velocity stages a step continues from."""
        if saved["state"].shape != self.batch.state.shape:
            raise ValueError(
                f"saved physics state has shape {saved['state'].shape}, this batch "
                f"{self.batch.state.shape} (another num_envs or model)"
            )
        for name, values in saved["model"].items():
            self.expand(name)[:] = torch.as_tensor(values)
        self.batch.set_const()
        self.batch.state[:] = saved["state"]
        self.batch.forward(stage=_STAGE_VEL)
        self._warnings_seen[:] = self._warning_count()

    def step(self, nstep: int, ids: torch.Tensor | None = None) -> torch.Tensor:
        """Advance all envs (or only envs `ids`) `nstep` physics steps; return the (num_envs,) mask of
        faulted envs. Envs left out keep their state exactly."""
        faulted = np.zeros(self.num_envs, dtype=bool)
        ids_np = None if ids is None else _index_array(ids)
        start = time.perf_counter()
        try:
            self.batch.step(ids=ids_np, nstep=nstep, stage=_STAGE_VEL)
        except mujoco.batch.SimulationError as err:
            faulted[err.ids] = True
        self.step_time_s += time.perf_counter() - start
        self.env_steps += self.num_envs if ids is None else len(ids)
        warnings = self._warning_count()
        faulted |= warnings != self._warnings_seen
        self._warnings_seen[:] = warnings
        # a non-finite value makes its array's sum non-finite: one fast reduction per array, and the
        # per-env search only when one is (or when the sum overflows, which also flags nothing wrong)
        for x in (self.qpos, self.qvel, self.sensordata):
            if not np.isfinite(x.numpy().sum()):
                faulted |= ~np.isfinite(x.numpy()).all(axis=1)
        return torch.from_numpy(faulted)

    def forward(self, ids: torch.Tensor | None = None) -> None:
        """Recompute the derived quantities of envs `ids` (all if None) after their state was written."""
        self.batch.forward(None if ids is None else _index_array(ids))

    def reset(
        self, ids: torch.Tensor, qpos: torch.Tensor, qvel: torch.Tensor, ctrl: torch.Tensor, set_const: bool
    ):
        """Fresh data for envs `ids` at the given state, derived quantities computed (mj_forward)."""
        ids_np = _index_array(ids)
        self.batch.reset(ids_np, stage=_STAGE_NONE)
        if set_const:  # masses / CoMs changed: refresh the constants mj_setConst derives from them
            self.batch.set_const(ids_np)
        self.qpos[ids] = qpos.to(self.dtype)
        self.qvel[ids] = qvel.to(self.dtype)
        self.ctrl[ids] = ctrl.to(self.dtype)
        self.batch.forward(ids_np)
        self._warnings_seen[ids_np] = self._warning_count()[ids_np]


def _readonly_view(a: np.ndarray) -> torch.Tensor:
    """A torch view of a Batch output (torch has no read-only tensors; numpy's flag is lifted only
    to share the memory, and nothing here writes to it)."""
    a = a.view()
    a.flags.writeable = True
    return torch.from_numpy(a)


def _index_array(ids) -> np.ndarray:
    """Env ids as the contiguous int array `Batch` takes."""
    if isinstance(ids, torch.Tensor):
        ids = ids.numpy()
    return np.ascontiguousarray(ids, dtype=np.int64)
