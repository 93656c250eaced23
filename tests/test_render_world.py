"""The visual-only render world (lasmp.render): decorations added to a copy of the physics model and
never to it, the ground below the platform's reach, a frame that shows a world, the caption, and the
follow camera keeping the robot in frame."""

from __future__ import annotations

import numpy as np
import pytest
import torch


@pytest.fixture(scope="module")
def plain_env():
    """An env of its own (the render tests move its state)."""
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    env = MovingPlatformEnv(build_env_cfg({"num_envs": 1, "seed": 0}, schema=MovingPlatformCfg))
    env.reset()
    return env


def _geom_names(model) -> list[str]:
    return [model.geom(i).name for i in range(model.ngeom)]


def test_render_model_has_physics_layout_and_visual_only_decorations(plain_env):
    from lasmp.render.world import DECOR_GROUP, DECOR_PREFIX, build_render_model

    phys = plain_env.sim.model
    model = build_render_model(plain_env)
    assert (model.nq, model.nv, model.na, model.nbody) == (phys.nq, phys.nv, phys.na, phys.nbody)
    np.testing.assert_array_equal(model.qpos0, phys.qpos0)
    assert [model.joint(i).name for i in range(model.njnt)] == [phys.joint(i).name for i in range(phys.njnt)]
    decor = [i for i, name in enumerate(_geom_names(model)) if name.startswith(DECOR_PREFIX)]
    assert len(decor) > 10  # the ground and the pillars' bands
    assert (model.geom_contype[decor] == 0).all() and (model.geom_conaffinity[decor] == 0).all()
    assert (model.geom_group[decor] == DECOR_GROUP).all() and (model.geom_bodyid[decor] == 0).all()
    assert model.ngeom == phys.ngeom + len(decor)  # nothing else added
    assert model.ntex >= 2 and "decor_sun" in [model.light(i).name for i in range(model.nlight)]


def test_physics_model_is_unchanged_by_rendering(plain_env):
    from lasmp.envs.moving_platform.scene import build_model
    from lasmp.render.world import DECOR_PREFIX, build_render_model

    phys = plain_env.sim.model
    before = (phys.ngeom, phys.nlight, phys.ntex, phys.nmat)
    build_render_model(plain_env)
    fresh = build_model(plain_env.cfg.platform, plain_env.cfg.sim)
    for m in (phys, fresh):
        assert (m.ngeom, m.nlight, m.ntex, m.nmat) == before
        assert not any(name.startswith(DECOR_PREFIX) for name in _geom_names(m))
        assert m.ntex == 0 and m.nlight == 1  # the robot, the platform and one light, no world


def test_ground_is_below_the_platforms_reach(plain_env):
    from lasmp.render.world import platform_layout

    size = plain_env.cfg.platform.size_m
    layout = platform_layout(size)
    # any rotation: the box's lowest point is at most its half-diagonal below its centre (z >= 0)
    assert layout.ground_z_m < -0.5 * float(np.linalg.norm(size)) - 0.5
    assert layout.ring_radius_m > 3.0  # pillars clear of the platform's |x|, |y| <= 1 m + half-diagonal


def _place(env, plf_pose, above_m: float = 0.45) -> None:
    """Platform joints (x, y, z, yaw, pitch, roll); the robot upright on it, trunk `above_m` over its centre."""
    import mujoco

    ix = env.index
    qpos = env.sim.qpos
    qpos[0, ix.plf_qpos] = torch.tensor(plf_pose, dtype=qpos.dtype)
    data = mujoco.MjData(env.sim.model)
    data.qpos[:] = qpos[0].numpy()
    mujoco.mj_kinematics(env.sim.model, data)
    plf = env.sim.model.body("platform").id
    qpos[0, ix.root_qpos : ix.root_qpos + 3] = torch.from_numpy(
        data.xpos[plf] + data.xmat[plf].reshape(3, 3) @ [0, 0, above_m]
    )
    qpos[0, ix.root_qpos + 3 : ix.root_qpos + 7] = torch.from_numpy(data.xquat[plf].copy())


def test_rendered_frame_shows_a_world_not_a_void(plain_env, gl):
    from lasmp.render.renderer import EnvRenderer

    r = EnvRenderer(plain_env)
    try:
        img = r.frame().astype(float)
    finally:
        r.close()
    assert img.mean() > 60  # not mostly black
    rows = img.mean(axis=(1, 2))
    assert abs(rows[: len(rows) // 8].mean() - rows[-len(rows) // 8 :].mean()) > 10  # sky above, ground below
    assert img[: len(rows) // 3].std() > 10  # the background itself is not uniform (grid, pillars)


def test_caption_changes_only_its_band():
    from lasmp.render.caption import caption_text, draw_caption

    text = caption_text(1.5, 7, 0.83, 2)
    assert text == "t  1.50 s   N 7   v_plf 0.83 m/s   collisions 2"
    assert caption_text(0.0, None, None, 0) == "t  0.00 s   collisions 0"
    img = np.full((480, 640, 3), 120, dtype=np.uint8)
    out = draw_caption(img.copy(), text)
    changed = (out != img).any(axis=-1)
    assert changed[:40].mean() > 0.5 and not changed[60:].any()  # a band at the top, nothing below
    assert (out[:40] > 200).all(axis=-1).sum() > 100  # white text on it


def test_frame_caption_reads_the_env(plain_env):
    from lasmp.render.renderer import frame_caption

    text = frame_caption(plain_env, 3)
    assert f"N {plain_env.traj_level[0]}" in text and "v_plf" in text and text.endswith("collisions 3")


@pytest.mark.parametrize(
    "plf_pose",
    [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (1.0, -1.0, 4.5, 0.5, 0.3, -0.4), (-1.0, 0.8, 2.0, -2.0, -0.35, 0.35)],
)
def test_follow_camera_keeps_robot_in_frame(plain_env, gl, plf_pose):
    import mujoco

    from lasmp.render.renderer import EnvRenderer

    _place(plain_env, plf_pose)
    r = EnvRenderer(plain_env)
    try:
        r.renderer.enable_segmentation_rendering()
        seg = r.frame()  # (H, W, 2): object id, object type
        m = r.model
        robot_geoms = np.flatnonzero(m.body_rootid[m.geom_bodyid] == m.body("trunk").id)
        is_geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
        robot = is_geom & np.isin(seg[..., 0], robot_geoms)
        platform = is_geom & (seg[..., 0] == m.geom("platform").id)
    finally:
        r.close()
    assert robot.mean() > 0.015, f"robot covers {robot.mean():.1%} of the frame"
    assert platform.mean() > 0.1
    ys, xs = np.nonzero(robot)
    h, w = robot.shape
    assert 0.15 * w < xs.mean() < 0.85 * w and 0.1 * h < ys.mean() < 0.9 * h  # well inside


def test_render_model_of_rough_static_task():
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.rough_static.cfg import RoughStaticCfg
    from lasmp.envs.rough_static.env import RoughStaticEnv
    from lasmp.render.world import DECOR_PREFIX, build_render_model

    env = RoughStaticEnv(build_env_cfg({"num_envs": 1}, schema=RoughStaticCfg))
    model = build_render_model(env)
    assert (model.nq, model.nv) == (env.sim.model.nq, env.sim.model.nv)
    decor = [i for i, name in enumerate(_geom_names(model)) if name.startswith(DECOR_PREFIX)]
    assert decor and (model.geom_contype[decor] == 0).all() and (model.geom_conaffinity[decor] == 0).all()
    assert not any(name.startswith(DECOR_PREFIX) for name in _geom_names(env.sim.model))
