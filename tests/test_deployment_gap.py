"""bench/deployment_gap.py's input modes: the shuffled-estimates probe feeds each env another env's x_exp."""

from pathlib import Path

import numpy as np
import pytest
import torch
from testkit import load_script

gap = load_script("bench/deployment_gap.py")


@pytest.mark.parametrize("n", [2, 3, 7, 1000])
def test_the_derangement_gives_every_env_another_envs_estimates(n):
    perm = gap.derangement(n, seed=n)
    assert sorted(perm.tolist()) == list(range(n))
    assert (perm != np.arange(n)).all()


def test_one_env_cannot_read_another_envs_estimates_and_is_refused_before_any_episode(capsys):
    with pytest.raises(ValueError, match="at least 2 envs"):
        gap.derangement(1)
    with pytest.raises(SystemExit):
        gap.main(["--checkpoint", "does-not-matter.pt", "--num-envs", "1", "--modes", "", "s"])
    assert "mode s" in capsys.readouterr().err


@pytest.fixture(scope="module")
def still_platform(tmp_path_factory):
    from lasmp.envs import trajectories as trj
    from lasmp.motions.motion import Motion, time_grid, to_trajectories

    path = tmp_path_factory.mktemp("still") / "still.npz"
    t = time_grid(2.0)
    trj.save(str(path), to_trajectories([Motion("still", t, np.zeros((len(t), 6)))]))
    return str(path)


def test_each_mode_feeds_the_actor_the_truth_it_names_and_the_shuffle_another_envs_estimates(still_platform):
    shipped = str(Path(__file__).resolve().parents[1] / "resources" / "policies" / "lasmp_a1.pt")
    env, pol = gap.mixed_policy(shipped, still_platform, 2.0, 3, 0, "s")
    obs = env.get_observations()
    inputs = {}
    with torch.inference_mode():
        for _ in range(5):  # a history of real steps, on other envs' estimates
            obs, *_ = env.step(pol(obs))
        pol(obs)  # the actor keeps the step it was called on as its truth
        for truth in ("", "x", "s", "l"):  # the same step read in each mode
            pol.truth = truth
            inputs[truth] = pol._estimated_inputs(obs["policy"], pol.normalize_history(obs["history"]))
        x_true = obs["priv_explicit"][:, : inputs[""][0].shape[1]]
        l_true = pol.encoder(obs["priv_implicit"])
    estimated, true_x, shuffled, true_l = (inputs[k] for k in ("", "x", "s", "l"))
    assert not torch.allclose(estimated[0], x_true, atol=1e-3)  # the estimates are not the truth
    torch.testing.assert_close(true_x[0], x_true)
    torch.testing.assert_close(shuffled[0], estimated[0][gap.derangement(3)])
    torch.testing.assert_close(shuffled[1], estimated[1])  # its own l_imp
    torch.testing.assert_close(true_l[1], l_true)
    torch.testing.assert_close(true_l[0], estimated[0])  # only l_imp replaced
    assert not torch.allclose(true_l[1], estimated[1], atol=1e-3)
