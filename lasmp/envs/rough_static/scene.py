"""The static rough-terrain world of the R-S baseline, built in code with `mujoco.MjSpec`.

World = our A1 (`lasmp.envs.robot_spec`: its MJCF, options, sensors) + one heightfield shared
by every env. The ground is generated from `TerrainCfg.seed`:
- the field is cut into square tiles; each tile is rough ground only, a gentle pyramid slope
  (0 at the tile border, peak <= `feature_height_m` at its centre) or a low square step
  (a raised block of height <= `feature_height_m`, half the tile wide);
- everywhere, smoothed uniform noise of amplitude `roughness_m` is added (legged_gym's
  "random uniform" terrain, smoothed by a box filter instead of interpolated).

Heightfield layout (MuJoCo): the geom sits at the origin, the grid spans
[-L_x/2, L_x/2] x [-L_y/2, L_y/2]; row r is y, column c is x; ground height = geom z +
size_z * data[r, c] with data in [0, 1]. The ground is contype 0, conaffinity 1, as the robot's
contacts want it; the sensors are the robot's only.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import torch
from scipy.ndimage import uniform_filter

from lasmp.config.base import SimCfg
from lasmp.envs.robot_spec import add_robot_sensors, robot_spec
from lasmp.envs.rough_static.cfg import TerrainCfg

HFIELD_NAME = "terrain"


class Heightfield:
    """A height grid (m) over a rectangle centred at the world origin, with look-ups."""

    def __init__(self, heights_m: np.ndarray, resolution_m: float):
        self.heights_m = heights_m  # (nrow = y, ncol = x)
        self.resolution_m = resolution_m
        self.nrow, self.ncol = heights_m.shape
        self.half_x_m = 0.5 * resolution_m * (self.ncol - 1)
        self.half_y_m = 0.5 * resolution_m * (self.nrow - 1)
        self._heights_t: dict = {}  # the grid as a tensor, per (device, dtype) looked up on

    def _grid(self, xy):
        gx = ((xy[..., 0] + self.half_x_m) / self.resolution_m).clip(0.0, self.ncol - 1.000001)
        gy = ((xy[..., 1] + self.half_y_m) / self.resolution_m).clip(0.0, self.nrow - 1.000001)
        return gx, gy

    def height_at(self, xy: torch.Tensor) -> torch.Tensor:
        """Bilinear ground height (m) under world points xy (..., 2), on xy's device and dtype."""
        key = (xy.device, xy.dtype)
        if key not in self._heights_t:
            self._heights_t[key] = torch.as_tensor(self.heights_m, dtype=xy.dtype, device=xy.device)
        h = self._heights_t[key]
        gx, gy = self._grid(xy)
        c, r = gx.floor().long(), gy.floor().long()
        fx, fy = gx - c, gy - r
        return (
            h[r, c] * (1 - fx) * (1 - fy)
            + h[r, c + 1] * fx * (1 - fy)
            + h[r + 1, c] * (1 - fx) * fy
            + h[r + 1, c + 1] * fx * fy
        )

    def max_height_near(self, xy: np.ndarray, radius_m: float) -> np.ndarray:
        """Highest grid point (m) within a square of half-side radius_m (+1 cell) around each xy (n, 2)."""
        gx, gy = self._grid(xy)
        k = int(math.ceil(radius_m / self.resolution_m)) + 1
        out = np.empty(len(xy))
        for i, (x, y) in enumerate(zip(gx, gy, strict=True)):
            c, r = int(x), int(y)
            out[i] = self.heights_m[max(r - k, 0) : r + k + 2, max(c - k, 0) : c + k + 2].max()
        return out


def generate_heights(cfg: TerrainCfg) -> np.ndarray:
    """(nrow, ncol) ground heights in m, min 0, from cfg.seed."""
    rng = np.random.default_rng(cfg.seed)
    ncol = int(round(cfg.size_m[0] / cfg.resolution_m)) + 1
    nrow = int(round(cfg.size_m[1] / cfg.resolution_m)) + 1
    h = np.zeros((nrow, ncol))
    tile = max(int(round(cfg.tile_m / cfg.resolution_m)), 2)
    yy, xx = np.meshgrid(np.arange(tile), np.arange(tile), indexing="ij")
    u = np.maximum(np.abs(xx / (tile - 1) - 0.5), np.abs(yy / (tile - 1) - 0.5)) * 2.0  # 0 centre .. 1 border
    for r0 in range(0, nrow, tile):
        for c0 in range(0, ncol, tile):
            kind = rng.choice(3, p=cfg.tile_kind_probs)
            peak = rng.uniform(0.25, 1.0) * cfg.feature_height_m
            if kind == 1:  # pyramid slope
                patch = peak * (1.0 - u)
            elif kind == 2:  # low step: a raised block half the tile wide
                patch = peak * (u <= 0.5)
            else:
                continue
            block = h[r0 : r0 + tile, c0 : c0 + tile]
            block += patch[: block.shape[0], : block.shape[1]]
    if cfg.roughness_m > 0:
        noise = rng.uniform(-1.0, 1.0, size=(nrow, ncol))
        noise = uniform_filter(noise, size=cfg.smoothing_cells, mode="wrap")
        noise *= cfg.roughness_m / max(np.abs(noise).max(), 1e-12)
        h += noise
    return h - h.min()


def build_spec(terrain: TerrainCfg, sim: SimCfg) -> tuple[mujoco.MjSpec, Heightfield]:
    spec = robot_spec(sim, "lasmp_rough_static")
    heights = generate_heights(terrain)
    hf = Heightfield(heights, terrain.resolution_m)
    top = max(float(heights.max()), 1e-3)
    spec.add_hfield(
        name=HFIELD_NAME,
        size=[hf.half_x_m, hf.half_y_m, top, 0.1],
        nrow=hf.nrow,
        ncol=hf.ncol,
        userdata=(heights / top).ravel().tolist(),  # already in [0, 1]: MuJoCo's normalization is a no-op
    )
    spec.worldbody.add_geom(
        name=HFIELD_NAME,
        type=mujoco.mjtGeom.mjGEOM_HFIELD,
        hfieldname=HFIELD_NAME,
        contype=0,
        conaffinity=1,
        friction=[terrain.friction, 0.005, 0.0001],
        rgba=[0.45, 0.5, 0.45, 1.0],
    )
    add_robot_sensors(spec)
    return spec, hf


def build_model(terrain: TerrainCfg, sim: SimCfg) -> tuple[mujoco.MjModel, Heightfield]:
    spec, hf = build_spec(terrain, sim)
    return spec.compile(), hf
