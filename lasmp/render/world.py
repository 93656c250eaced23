"""The visual-only world for rendering: ground grid, sky, lights and reference pillars.

The physics model of a task (`lasmp.envs.moving_platform.scene` / `lasmp.envs.rough_static.scene`) is a robot
and a platform (or a heightfield) in an empty world, tuned for stepping speed. To make the
platform's motion visible, rendering uses a second model: the same `MjSpec` plus decorations
that change nothing physical:
- a large checker-grid ground plane (1 m cells with light edges), for the moving platform far
  below anything the platform can reach (`ground_z_m`);
- a gradient skybox, a headlight, a directional sun and, for the moving platform, a spot light
  riding along above it; one light casts shadows (the spot, else the sun), one shadow pass a frame;
- a ring of pillars banded every `BAND_M` metres, fixed height references for the platform's
  x/y/z motion.
Every decoration is a world-body geom with contype = conaffinity = 0 in `DECOR_GROUP`; no body
or joint is added, so the render model's qpos/qvel layout is the physics model's
(`build_render_model` checks it) and its state is a plain copy of one env's qpos/qvel. The
physics model never sees any of this: it is compiled from its own spec, without decorations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

DECOR_PREFIX = "decor_"  # name prefix of everything added here
DECOR_GROUP = 2  # geom group of the decorations (visible by default in Renderer and viewer)
GROUND_CLEARANCE_M = 1.0  # ground below the lowest reach of the platform: covers spline undershoot of z < 0
GROUND_HALF_M = 60.0  # half-side of the ground plane, m
CELL_M = 1.0  # checker cell, m
BAND_M = 1.0  # height of one pillar band, m
PILLAR_COUNT = 8
PILLAR_RADIUS_M = 0.12
SPOT_HEIGHT_M = 4.0  # the platform's spot light sits this far above it, m
SPOT_CUTOFF_DEG = 40.0  # its cone half-angle: the 2 m platform and its robot, seen from SPOT_HEIGHT_M


@dataclass(frozen=True)
class WorldLayout:
    """Where the decorations go (world frame, m)."""

    ground_z_m: float  # height of the ground plane
    ring_radius_m: float  # pillars stand on this circle around the origin
    pillar_top_z_m: float  # pillars reach from the ground up to here
    spot_body: str | None = None  # a shadow-casting spot light follows this body


def platform_layout(platform_size_m, z_max_m: float = 5.0) -> WorldLayout:
    """Layout for the moving platform: its centre starts at the origin, stays in |x|, |y| <= ~1 m and
    z in ~[0, z_max_m]. The platform's lowest point is at most its half-diagonal below its centre
    (any rotation), so the ground goes GROUND_CLEARANCE_M below that and the platform never meets it."""
    half_diag = 0.5 * float(np.linalg.norm(platform_size_m))
    ground = -(half_diag + GROUND_CLEARANCE_M)
    return WorldLayout(
        ground_z_m=ground, ring_radius_m=6.0, pillar_top_z_m=z_max_m + 2.0, spot_body="platform"
    )


def terrain_layout(half_x_m: float, half_y_m: float) -> WorldLayout:
    """Layout for a static heightfield centred at the origin with heights >= 0: the grid lies just
    under the field's lowest point (and shows beyond its edges); pillars stand outside it."""
    return WorldLayout(
        ground_z_m=-0.01, ring_radius_m=math.hypot(half_x_m, half_y_m) + 2.0, pillar_top_z_m=3.0
    )


def decorate(spec: mujoco.MjSpec, layout: WorldLayout) -> None:
    """Add the visual-only world to `spec` in place (geoms, textures, materials, lights; no bodies or
    joints: the spot light of `layout.spot_body` is a light of that body, not a body of its own)."""
    p = DECOR_PREFIX
    vis = spec.visual
    vis.headlight.ambient = [0.3, 0.3, 0.3]
    vis.headlight.diffuse = [0.3, 0.3, 0.3]
    vis.headlight.specular = [0.05, 0.05, 0.05]
    # one shadow pass per frame; a larger map costs more in software GL (docs/performance.md)
    vis.quality.shadowsize = 2048
    # the scene's own lights: dimmer, no shadows (one decor light casts them)
    for light in spec.worldbody.lights:
        light.castshadow = False
        light.diffuse = [0.35, 0.35, 0.35]
    vis.rgba.haze = [0.75, 0.85, 0.95, 1.0]  # the horizon fades into the sky's colour

    spec.add_texture(
        name=f"{p}sky",
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[0.35, 0.55, 0.85],
        rgb2=[0.9, 0.93, 0.97],
        width=256,
        height=1536,
    )
    spec.add_texture(
        name=f"{p}grid",
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        mark=mujoco.mjtMark.mjMARK_EDGE,
        rgb1=[0.32, 0.36, 0.38],
        rgb2=[0.42, 0.46, 0.48],
        markrgb=[0.85, 0.85, 0.85],
        width=512,
        height=512,
    )
    grid = spec.add_material(name=f"{p}grid", texrepeat=[1.0 / (2 * CELL_M)] * 2, texuniform=True)
    grid.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{p}grid"

    world = spec.worldbody

    def geom(name: str, **kw) -> None:
        world.add_geom(name=p + name, contype=0, conaffinity=0, group=DECOR_GROUP, mass=0.0, **kw)

    geom(
        "ground",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[GROUND_HALF_M, GROUND_HALF_M, 1.0],
        pos=[0.0, 0.0, layout.ground_z_m],
        material=f"{p}grid",
    )
    # banded pillars: one cylinder per BAND_M, alternating colours, bands at whole metres of z
    z0 = math.floor(layout.ground_z_m)
    n_bands = math.ceil((layout.pillar_top_z_m - z0) / BAND_M)
    colours = ([0.85, 0.35, 0.15, 1.0], [0.95, 0.95, 0.92, 1.0])
    for i in range(PILLAR_COUNT):
        a = 2.0 * math.pi * (i + 0.5) / PILLAR_COUNT
        x, y = layout.ring_radius_m * math.cos(a), layout.ring_radius_m * math.sin(a)
        for b in range(n_bands):
            lo = max(z0 + b * BAND_M, layout.ground_z_m)
            hi = z0 + (b + 1) * BAND_M
            geom(
                f"pillar{i}_band{b}",
                type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                size=[PILLAR_RADIUS_M, 0.5 * (hi - lo), 0.0],
                pos=[x, y, 0.5 * (lo + hi)],
                rgba=colours[(z0 + b) % 2],
            )

    # a sun: directional, from above and to the side; it casts the shadows unless a spot follows a body
    sun_dir = [0.3, 0.5, -1.0]
    world.add_light(
        name=f"{p}sun",
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        pos=[0.0, 0.0, layout.pillar_top_z_m + 5.0],
        dir=sun_dir,
        diffuse=[0.5, 0.5, 0.5],
        specular=[0.1, 0.1, 0.1],
        castshadow=layout.spot_body is None,
    )
    if layout.spot_body is not None:
        # a spot riding along with the body (offset fixed in the world, not turning with it): its
        # narrow shadow map gives the robot a sharp shadow where a sun's would cover the whole world
        body = spec.body(layout.spot_body)
        offset = -SPOT_HEIGHT_M * np.asarray(sun_dir) / abs(sun_dir[2])
        body.add_light(
            name=f"{p}spot",
            type=mujoco.mjtLightType.mjLIGHT_SPOT,
            mode=mujoco.mjtCamLight.mjCAMLIGHT_TRACK,
            pos=offset.tolist(),
            dir=sun_dir,
            cutoff=SPOT_CUTOFF_DEG,
            exponent=1.0,
            diffuse=[0.35, 0.35, 0.35],
            specular=[0.1, 0.1, 0.1],
            castshadow=True,
        )


def physics_spec(env) -> tuple[mujoco.MjSpec, WorldLayout]:
    """The spec the env's physics model is compiled from (rebuilt from its config), and its layout."""
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.envs.rough_static.env import RoughStaticEnv

    cfg = env.cfg
    if isinstance(env, MovingPlatformEnv):
        from lasmp.envs.moving_platform.scene import build_spec

        return build_spec(cfg.platform, cfg.sim), platform_layout(cfg.platform.size_m)
    if isinstance(env, RoughStaticEnv):
        from lasmp.envs.rough_static.scene import build_spec

        spec, hf = build_spec(cfg.terrain, cfg.sim)
        return spec, terrain_layout(hf.half_x_m, hf.half_y_m)
    raise TypeError(f"no render world for env type {type(env).__name__}")


def build_render_model(env) -> mujoco.MjModel:
    """The env's scene plus the visual-only world, compiled on its own (the env's model is untouched).

    Raises if the decorations changed the state layout (they add no joint, so they must not).
    """
    spec, layout = physics_spec(env)
    decorate(spec, layout)
    model = spec.compile()
    phys = env.sim.model
    for field in ("nq", "nv", "na", "nbody", "njnt"):
        if getattr(model, field) != getattr(phys, field):
            raise AssertionError(
                f"render model {field} = {getattr(model, field)} != physics model {field} = {getattr(phys, field)}"
            )
    return model
