"""CPU physics backend: all envs of one model on `mujoco.batch.Batch` (MuJoCo >= 4.0).

One call steps every simulation `nstep` substeps on a C thread pool (no Python loop over envs
or substeps). The batch is persistent (one MjData per env) so that the stage computed after a
step (`mjSTAGE_VEL`: positions, velocities and their sensors current at the new state) is
reused by the next step at no extra cost; acceleration-stage sensors (accelerometer, contact
sensors) then describe the last substep, 1 physics dt old.

Faults are data: `step` returns a boolean mask of simulations that raised a MuJoCo error,
raised a warning (e.g. a bad qacc that made MuJoCo reset the data itself) or hold non-finite
state. The caller terminates and resets those envs alone.
"""

from __future__ import annotations

import time

import mujoco
import mujoco.batch
import numpy as np

_STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_VEL)
_STAGE_NONE = int(mujoco.mjtStage.mjSTAGE_NONE)


class CpuBatchSim:
    def __init__(self, model: mujoco.MjModel, num_envs: int, num_threads: int = 0):
        self.model = model
        self.num_envs = num_envs
        self.batch = mujoco.batch.Batch(model, num_envs, nthread=num_threads, persistent=True)
        b = self.batch
        # live views: state rows (writable) and derived outputs (read-only, refreshed by every call)
        self.qpos = b.bind("qpos")
        self.qvel = b.bind("qvel")
        self.ctrl = b.bind("ctrl")
        self.act = b.bind("act")
        self.sensordata = b.bind("sensordata")
        self.site_xpos = b.bind("site_xpos")
        self.actuator_force = b.bind("actuator_force")
        self._warnings_seen = self._warning_count().copy()
        self._expanded: list[str] = []  # model fields given per-env values (domain randomization)
        self.step_time_s = 0.0  # wall time spent inside Batch.step, for benchmarks
        self.env_steps = 0  # policy steps simulated, summed over envs (fewer with `ids`), for benchmarks

    def _warning_count(self) -> np.ndarray:
        return self.batch.warning[:, :, 1].sum(axis=1)  # (nsim,) total warnings raised so far

    def expand(self, name: str) -> np.ndarray:
        """Per-env values of a model field, (num_envs, ...), live."""
        if name not in self._expanded:
            self._expanded.append(name)
        return self.batch.expand(name)

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
            raise ValueError(f"saved physics state has shape {saved['state'].shape}, this batch "
                             f"{self.batch.state.shape} (another num_envs or model)")  # fmt: skip
        for name, values in saved["model"].items():
            self.expand(name)[:] = values
        self.batch.set_const()
        self.batch.state[:] = saved["state"]
        self.batch.forward(stage=_STAGE_VEL)
        self._warnings_seen[:] = self._warning_count()

    def step(self, nstep: int, ids: np.ndarray | None = None) -> np.ndarray:
        """Advance all envs (or only envs `ids`) `nstep` physics steps; return the (num_envs,) mask of
        faulted envs. Envs left out keep their state exactly."""
        faulted = np.zeros(self.num_envs, dtype=bool)
        start = time.perf_counter()
        try:
            self.batch.step(ids=ids, nstep=nstep, stage=_STAGE_VEL)
        except mujoco.batch.SimulationError as err:
            faulted[err.ids] = True
        self.step_time_s += time.perf_counter() - start
        self.env_steps += self.num_envs if ids is None else len(ids)
        warnings = self._warning_count()
        faulted |= warnings != self._warnings_seen
        self._warnings_seen[:] = warnings
        faulted |= ~np.isfinite(self.qpos).all(axis=1) | ~np.isfinite(self.qvel).all(axis=1)
        faulted |= ~np.isfinite(self.sensordata).all(axis=1)
        return faulted

    def reset(self, ids: np.ndarray, qpos: np.ndarray, qvel: np.ndarray, ctrl: np.ndarray, set_const: bool):
        """Fresh data for envs `ids` at the given state, derived quantities computed (mj_forward)."""
        self.batch.reset(ids, stage=_STAGE_NONE)
        if set_const:  # masses / CoMs changed: refresh the constants mj_setConst derives from them
            self.batch.set_const(ids)
        self.qpos[ids] = qpos
        self.qvel[ids] = qvel
        self.ctrl[ids] = ctrl
        self.batch.forward(ids)
        self._warnings_seen[ids] = self._warning_count()[ids]
