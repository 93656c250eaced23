"""play.py playing a checkpoint from its own config: the summary it prints, the seed's episodes,
the deployed policy (blind to the privileged groups), benchmark episodes and real-motion scenarios,
the small policy checkpoint, and the study's R-S checkpoint."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf
from testkit import PLAY_LATENT_DIM as LATENT_DIM
from testkit import ROOT

from lasmp.cli.play import main
from lasmp.deploy import load_deploy_env

PRIVILEGED = ("priv_explicit", "priv_implicit", "alignment", "critic")


def test_play_runs_and_prints_summary(run_dir, capsys):
    from lasmp.algo.checkpoint import latest_checkpoint

    assert main(["--checkpoint", str(run_dir), "--steps", "50", "--num-envs", "2"]) == 0
    out = capsys.readouterr().out
    newest = latest_checkpoint(run_dir)  # the file the run directory stands for
    assert f"loaded {newest} (iteration 0, task moving_platform)" in out
    assert "played 50 steps x 2 envs" in out
    assert "episodes ended" in out and "collisions" in out and "mean reward per step" in out


def test_a_seed_gives_other_episodes_and_no_seed_continues_the_checkpoints_own_streams(run_dir):
    def first_episode(seed):
        env, _, cfg, _ = load_deploy_env(run_dir, num_envs=1, seed=seed)
        pose, _, _ = env.traj.evaluate(np.array([2.0]))
        return cfg.seed, pose, env.intrinsics.trunk_mass_kg.copy()

    (s1, pose1, mass1), (_, pose1b, mass1b), (s2, pose2, mass2) = map(first_episode, (1, 1, 2))
    assert (s1, s2) == (1, 2)
    assert np.array_equal(pose1, pose1b) and np.array_equal(mass1, mass1b)
    assert not np.array_equal(pose1, pose2) and not np.array_equal(mass1, mass2)
    (own, pose_own, _), (_, pose_own_b, _) = first_episode(None), first_episode(None)
    assert own == 0 and np.array_equal(pose_own, pose_own_b)  # the run's seed, its streams at the save
    assert not np.array_equal(pose_own, first_episode(0)[1])  # not its seed's fresh streams


def test_policy_from_checkpoint_config_and_deploy_ignores_privileged(loaded):
    env, policy, cfg, _ = loaded
    assert cfg.policy.latent_dim == LATENT_DIM and cfg.env.num_envs == 1 and cfg.seed == 3
    assert policy.latent_dim == LATENT_DIM and policy.deploy and not policy.training
    assert policy.mlp[0].out_features == 32  # the checkpoint's hidden dims, not today's 512
    obs = env.get_observations()
    nan_obs = obs.clone()
    for group in PRIVILEGED:
        nan_obs[group] = torch.full_like(nan_obs[group], float("nan"))
    with torch.inference_mode():
        actions = policy(obs)
        assert torch.isfinite(actions).all()
        torch.testing.assert_close(policy(nan_obs), actions, rtol=0, atol=0)


def test_benchmark_episode_on_a_fresh_clone_makes_the_default_benchmark_as_evaluate_does(
    run_dir, tmp_path, monkeypatch
):
    from lasmp.cli.play import use_benchmark_episodes
    from lasmp.deploy import load_deploy_env
    from lasmp.eval import benchmark as bm

    monkeypatch.chdir(tmp_path)  # no benchmarks/ here
    env, _, _, _ = load_deploy_env(str(run_dir), num_envs=1)
    use_benchmark_episodes(env, "benchmarks/xi_eval.npz", 3)
    bench = bm.load(tmp_path / "benchmarks" / "xi_eval.npz")
    assert bench.num_episodes == 10_000
    assert env.intrinsics.trunk_mass_kg[0] == bench.robots.trunk_mass_kg[3]


def test_benchmark_episode_plays_that_trajectory_and_robot(run_dir, tmp_path, capsys):
    from lasmp.cli.play import use_benchmark_episodes
    from lasmp.deploy import load_deploy_env
    from lasmp.eval import benchmark as bm

    bench_path = tmp_path / "bench.npz"
    bench = bm.generate(num_trajectories=6, num_robots=2, seed=0)
    bm.save(bench_path, bench)
    env, _, _, _ = load_deploy_env(str(run_dir), num_envs=1)
    use_benchmark_episodes(env, str(bench_path), 3)
    pose_env, _, _ = env.traj.evaluate(np.array([2.0]))
    pose_bench, _, _ = bench.trajectories.evaluate(np.array([2.0]), rows=[3])
    assert np.array_equal(pose_env, pose_bench)
    assert env.intrinsics.trunk_mass_kg[0] == bench.robots.trunk_mass_kg[3 % 2]
    assert (
        main(
            [
                "--checkpoint",
                str(run_dir),
                "--benchmark",
                str(bench_path),
                "--benchmark-episode",
                "9",
                "--steps",
                "1",
            ]
        )
        == 2
    )
    assert "--benchmark-episode must be in [0, 5]" in capsys.readouterr().err


def test_scenario_plays_the_real_motion_on_the_close_drive(run_dir, capsys, monkeypatch):
    import lasmp.cli.play as play
    from lasmp.eval.real_motion import suite as rm

    seen = {}
    real_load = play.load_deploy_env

    def spy(*args):
        out = real_load(*args)
        seen.update(env=out[0], file=args[3])
        return out

    monkeypatch.setattr(play, "load_deploy_env", spy)
    assert main(["--checkpoint", str(run_dir), "--scenario", "lift_up", "--steps", "3"]) == 0
    assert "played 3 steps x 1 envs" in capsys.readouterr().out
    env = seen["env"]
    (lift,) = rm.build_motions(["lift_up"])
    assert env.max_episode_length == round(lift.duration_s / env.dt_s)  # the scenario's length, not 10 s
    assert env.cfg.platform.velocity_feedforward and env.cfg.platform.omega_n_rad_s == pytest.approx(25.13)
    pose, _, _ = env.traj.evaluate(np.array([8.0]))
    np.testing.assert_allclose(pose[0], lift.pose[800], atol=1e-9)
    assert not Path(seen["file"]).exists()  # the temporary file is removed once loaded
    assert main(["--checkpoint", str(run_dir), "--scenario", "rocket"]) == 2
    assert "unknown scenario(s) ['rocket']" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--checkpoint", str(run_dir), "--scenario", "lift_up", "--trajectories", "x.npz"])


def test_policy_checkpoint_is_small_plays_the_same_and_refuses_to_resume(run_dir, tmp_path):
    from lasmp.algo.checkpoint import CheckpointError, latest_checkpoint, read_checkpoint
    from lasmp.algo.checkpoint import main as ckpt_main
    from lasmp.cli.build import make_runner
    from lasmp.config.train import to_train_cfg
    from lasmp.deploy import load_deploy_env

    full = latest_checkpoint(run_dir)
    slim = tmp_path / "policy.pt"
    assert ckpt_main(["policy", str(run_dir), str(slim)]) == 0
    data = read_checkpoint(slim)
    assert data["kind"] == "policy" and "optimizer_state_dict" not in data
    assert "estimator_optimizer_state_dict" not in data and slim.stat().st_size < 0.6 * full.stat().st_size
    env_a, pol_a, _, _ = load_deploy_env(full, num_envs=2, seed=1)
    env_b, pol_b, _, _ = load_deploy_env(slim, num_envs=2, seed=1)
    with torch.inference_mode():
        for _ in range(5):
            act_a, act_b = pol_a(env_a.get_observations()), pol_b(env_b.get_observations())
            assert torch.equal(act_a, act_b)
            env_a.step(act_a)
            env_b.step(act_b)
    runner = make_runner(to_train_cfg(OmegaConf.create(data["config"])), None)
    with pytest.raises(CheckpointError, match="policy checkpoint.*to resume training"):
        runner.load(str(slim))
    assert ckpt_main(["policy", str(tmp_path / "nope"), str(tmp_path / "x.pt")]) == 2


def test_the_studys_r_s_checkpoint_plays_and_its_export_is_refused_in_one_line(tmp_path, capsys):
    # the rough-static config has no trajectory hold: play sets it for moving-platform checkpoints only
    rs = ROOT / "results" / "study" / "rs" / "seed0" / "policy_449.pt"
    assert main(["--checkpoint", str(rs), "--steps", "5"]) == 0
    out = capsys.readouterr().out
    assert "task rough_static" in out and "played 5 steps" in out
    # the deployable policy takes the proprioceptive window alone; R-S also needs a velocity command
    assert main(["--checkpoint", str(rs), "--steps", "0", "--export", "onnx", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --export: ") and "command" in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())
