"""MuJoCo Warp physics backend: all envs of one model as the worlds of one `mujoco_warp.Data`.

The same compiled `mujoco.MjModel` as the CPU backend goes to the device with
`mujoco_warp.put_model`; every world steps in the same kernels, float32. The state and outputs are
`warp.to_torch` views of the Warp arrays (no copies), on the torch device matching the Warp device:
a CUDA GPU for training, or Warp's CPU device (how the tests compare it with C MuJoCo).

Per-env model fields (domain randomization) use MuJoCo Warp's batched model fields: a model array
whose leading dimension is 1 is shared by all worlds, one of length nworld holds a row per world.
`expand(name)` turns a field into the per-world kind on first use. The constants `set_const`
derives from masses and CoMs are batched from the start, as they then differ per world too.

`mujoco_warp.step` leaves the derived quantities one substep old (they describe the state it
started from). The contract wants positions, velocities and their sensors at the new state, so
after the substeps the position and velocity stages run once more (what `mj_step1` does, and
what the CPU backend's `mjSTAGE_VEL` does); acceleration quantities keep the last substep's.

Faults: a world faults when its qpos, qvel or sensordata holds a non-finite value, or when
MuJoCo Warp flags an overflow in it (`Data.overflow`, a per-world bitmask, sticky until cleared:
we clear it after each step). Two of its bits are global in cause: contacts live in one pool
shared by all worlds (`naconmax`), so a broadphase or narrowphase overflow is flagged in every
world; each world's own contacts may then be missing, so every world is faulted. Reaching the
solver's iteration limit is flagged too, but C MuJoCo treats it as normal: not a fault here.

On CUDA the `nstep`-substep loop (and the stages after it) is captured into a CUDA graph on its
second call for a given `nstep` (the first runs eagerly: it compiles the kernels, which a capture
cannot) and replayed afterwards.
"""

from __future__ import annotations

import time
from contextlib import contextmanager

import mujoco
import numpy as np
import torch

# Constants mujoco_warp's set_const derives per world from body_mass / body_ipos (its FIXED and
# INERT0 groups). set_const writes as many rows as the field has, so they are batched up front.
_DERIVED_CONSTANTS = (
    "body_subtreemass",
    "body_invweight0",
    "dof_invweight0",
    "tendon_invweight0",
    "actuator_acc0",
)


def _import_warp():
    """warp and mujoco_warp, or an ImportError that says how to install them (the `gpu` extra)."""
    try:
        import mujoco_warp
        import warp
    except ImportError as err:
        raise ImportError(
            f"env.backend=warp needs MuJoCo Warp ({err}); install it with "
            'pip install -e ".[gpu]" (the gpu extra: mujoco-warp and warp-lang)'
        ) from err
    return warp, mujoco_warp


class WarpSim:
    dtype = torch.float32

    def __init__(self, model: mujoco.MjModel, num_envs: int, sim_cfg, device: torch.device | str = "cpu"):
        wp, mjw = _import_warp()
        wp.init()  # idempotent; the device look-up below needs Warp's runtime
        self._wp, self._mjw = wp, mjw
        self.model = model
        self.num_envs = num_envs
        self.device = torch.device(device)
        if self.device.type == "cuda" and self.device.index is None:
            self.device = torch.device("cuda", torch.cuda.current_device())
        self._wp_device = wp.device_from_torch(self.device)
        # kernels can't compile during a capture, and Warp's CPU device has no graphs
        self._use_graphs = self.device.type == "cuda"
        self._graphs: dict[int, object] = {}  # nstep -> captured graph
        self._eager_done: set[int] = set()  # nstep values already run once (kernels compiled)
        self._graph_stream = wp.Stream(self._wp_device) if self._use_graphs else None

        n = num_envs
        with self._on_device():
            self._m = mjw.put_model(model, batch_sizes={name: n for name in _DERIVED_CONSTANTS})
            # the solver's iteration limits are not faults (see the module docstring); no kernel printf
            # for overflows either: they come back as data in `step`'s mask
            self._m.opt.warn_overflow = 0
            self._d = mjw.make_data(
                model, nworld=n, nconmax=sim_cfg.warp_contacts_per_env, njmax=sim_cfg.warp_constraints_per_env
            )
            ot = mjw.OverflowType
            self._fault_bits = int(ot.ALL & ~(ot.ITERATIONS | ot.LS_ITERATIONS))
            # mujoco_warp's own constants from the start: a later set_const then recomputes the
            # unchanged worlds' values bit for bit (C MuJoCo's float64 ones would shift slightly)
            mjw.set_const(self._m, self._d, restore=False)
            mjw.reset_data(self._m, self._d)
            mjw.forward(self._m, self._d)

        d = self._d
        # live views: state rows (writable) and derived outputs (read-only, refreshed by every call)
        self.qpos = wp.to_torch(d.qpos)
        self.qvel = wp.to_torch(d.qvel)
        self.ctrl = wp.to_torch(d.ctrl)
        self.act = wp.to_torch(d.act)
        self.sensordata = wp.to_torch(d.sensordata)
        self.site_xpos = wp.to_torch(d.site_xpos)  # (n, nsite, 3): vec3 becomes a trailing dim
        self.actuator_force = wp.to_torch(d.actuator_force)
        self._overflow = wp.to_torch(d.overflow)
        # the integration state, as mj_getState's signature names it (what a resume or a left-out env keeps)
        self._sig = int(mjw.State.INTEGRATION)
        self._state_buf = wp.zeros(
            (n, mujoco.mj_stateSize(model, self._sig)), dtype=float, device=self._wp_device
        )
        self._expanded: list[str] = []  # model fields given per-env values (domain randomization)
        self.step_time_s = 0.0  # wall time spent in the physics, for benchmarks
        self.env_steps = 0  # policy steps simulated, summed over envs (fewer with `ids`), for benchmarks

    # -- device plumbing ---------------------------------------------------------------------------
    @contextmanager
    def _on_device(self):
        """Warp work on our device; on CUDA on torch's current stream, so that it is ordered with
        the torch reads and writes of the views around it."""
        wp = self._wp
        with wp.ScopedDevice(self._wp_device):
            if self.device.type != "cuda":
                yield
                return
            with wp.ScopedStream(wp.stream_from_torch(self.device)):
                yield

    def _mask(self, ids: torch.Tensor) -> torch.Tensor:
        mask = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        mask[ids] = True
        return mask

    def _ids(self, ids) -> torch.Tensor:
        return torch.as_tensor(ids, dtype=torch.long, device=self.device)

    # -- model fields ------------------------------------------------------------------------------
    def expand(self, name: str) -> torch.Tensor:
        """Per-env values of a model field, (num_envs, ...), live and writable."""
        wp = self._wp
        field = getattr(self._m, name, None)
        if not isinstance(field, wp.array):
            raise ValueError(f"{name!r} is not an array field of the MuJoCo Warp model")
        if field.shape[0] != self.num_envs:
            if field.shape[0] != 1:
                raise ValueError(
                    f"model field {name!r} has a leading dim of {field.shape[0]}, not 1 (shared)"
                )
            rows = np.repeat(field.numpy(), self.num_envs, axis=0)
            # a new array: a captured graph still reads the old one, so capture again
            setattr(self._m, name, wp.array(rows, dtype=field.dtype, device=self._wp_device))
            self._graphs.clear()
        if name not in self._expanded:
            self._expanded.append(name)
        return wp.to_torch(getattr(self._m, name))

    # -- stepping ----------------------------------------------------------------------------------
    def _pos_vel_stages(self) -> None:
        """Positions, velocities and their sensors at the current state (mj_step1 without the control
        callback); sensordata is not cleared, so acceleration sensors keep the last substep's values."""
        m, d, mjw = self._m, self._d, self._mjw
        mjw.fwd_position(m, d, factorize=False)
        mjw.sensor_pos(m, d)
        mjw.fwd_velocity(m, d)
        mjw.sensor_vel(m, d)

    def _substeps(self, nstep: int) -> None:
        for _ in range(nstep):
            self._mjw.step(self._m, self._d)
        self._pos_vel_stages()

    def _run_substeps(self, nstep: int) -> None:
        wp = self._wp
        if not self._use_graphs or nstep not in self._eager_done:
            self._substeps(nstep)
            self._eager_done.add(nstep)
            return
        # a graph can't be captured on torch's (legacy) default stream: capture and replay on a stream
        # of our own, which waits for the work before it and is waited for by the work after it
        with wp.ScopedStream(self._graph_stream, sync_enter=True, sync_exit=True):
            if nstep not in self._graphs:
                with wp.ScopedCapture(device=self._wp_device, stream=self._graph_stream) as capture:
                    self._substeps(nstep)
                self._graphs[nstep] = capture.graph
            wp.capture_launch(self._graphs[nstep])

    @contextmanager
    def _keep_others(self, ids: torch.Tensor | None):
        """Envs not in `ids` come out as they went in: their integration state (mujoco_warp's
        get/set_state, masked) and their derived outputs in the contract. The kernels still run on
        every world; what they computed for the others is discarded."""
        if ids is None:
            yield
            return
        m, d, mjw, wp = self._m, self._d, self._mjw, self._wp
        others = ~self._mask(ids)
        outputs = (self.sensordata, self.site_xpos, self.actuator_force, self._overflow)
        saved = [x[others].clone() for x in outputs]
        mjw.get_state(m, d, self._state_buf, self._sig)
        yield
        mjw.set_state(m, d, self._state_buf, self._sig, active=wp.from_torch(others))
        for x, rows in zip(outputs, saved, strict=True):
            x[others] = rows

    def step(self, nstep: int, ids: torch.Tensor | None = None) -> torch.Tensor:
        """Advance all envs (or only envs `ids`) `nstep` physics steps; return the (num_envs,) mask of
        faulted envs. Envs left out keep their state exactly."""
        ids = None if ids is None else self._ids(ids)
        start = time.perf_counter()
        with self._on_device():
            with self._keep_others(ids):
                self._run_substeps(nstep)
        if self.device.type == "cuda":  # the launches are asynchronous; time the work, not the queueing
            torch.cuda.synchronize(self.device)
        self.step_time_s += time.perf_counter() - start
        self.env_steps += self.num_envs if ids is None else len(ids)

        faulted = (self._overflow & self._fault_bits) != 0
        self._overflow.zero_()
        for x in (self.qpos, self.qvel, self.sensordata):  # a non-finite value makes its row's sum so
            faulted |= ~torch.isfinite(x.sum(dim=1))
        return faulted

    # -- resets ------------------------------------------------------------------------------------
    def forward(self, ids: torch.Tensor | None = None) -> None:
        """Recompute the derived quantities of envs `ids` (all if None) after their state was written
        (mj_forward: acceleration quantities too, at the current state)."""
        ids = None if ids is None else self._ids(ids)
        with self._on_device(), self._keep_others(ids):
            self._mjw.forward(self._m, self._d)

    def reset(
        self, ids: torch.Tensor, qpos: torch.Tensor, qvel: torch.Tensor, ctrl: torch.Tensor, set_const: bool
    ):
        """Fresh data for envs `ids` at the given state, derived quantities computed (mj_forward)."""
        ids = self._ids(ids)
        if len(ids) == 0:
            return
        m, d, mjw, wp = self._m, self._d, self._mjw, self._wp
        with self._on_device(), self._keep_others(ids):
            mjw.reset_data(m, d, wp.from_torch(self._mask(ids)))
            if set_const:
                # masses / CoMs changed: refresh the constants derived from them. mujoco_warp has no
                # per-world mask here; the other worlds' unchanged fields give their values back exactly
                mjw.set_const(m, d, restore=False)
            self.qpos[ids] = torch.as_tensor(qpos, dtype=self.dtype, device=self.device)
            self.qvel[ids] = torch.as_tensor(qvel, dtype=self.dtype, device=self.device)
            self.ctrl[ids] = torch.as_tensor(ctrl, dtype=self.dtype, device=self.device)
            mjw.forward(m, d)  # what it flags for the fresh state is reported by the next step

    # -- checkpoints -------------------------------------------------------------------------------
    def get_state(self) -> dict:
        """Everything a later `set_state` needs to continue bit for bit: each env's integration state
        (positions, velocities, actuator states, controls, warm start, time, ...) and the per-env
        model fields, as CPU tensors."""
        with self._on_device():
            self._mjw.get_state(self._m, self._d, self._state_buf, self._sig)
        return {
            "state": self._wp.to_torch(self._state_buf).cpu().clone(),
            "model": {name: self.expand(name).cpu().clone() for name in self._expanded},
        }

    def set_state(self, saved: dict) -> None:
        """Restore `get_state` output: the model fields (and the constants derived from them), the
        integration state, and the position and velocity stages a step continues from."""
        shape = tuple(self._state_buf.shape)
        if tuple(saved["state"].shape) != shape:
            raise ValueError(
                f"saved physics state has shape {tuple(saved['state'].shape)}, this backend "
                f"{shape} (another num_envs or model)"
            )
        for name, values in saved["model"].items():
            view = self.expand(name)
            view[:] = torch.as_tensor(values).to(view)
        with self._on_device():
            self._mjw.set_const(self._m, self._d, restore=False)
            self._wp.to_torch(self._state_buf)[:] = torch.as_tensor(saved["state"], device=self.device)
            self._mjw.set_state(self._m, self._d, self._state_buf, self._sig)
            self._pos_vel_stages()
        self._overflow.zero_()
