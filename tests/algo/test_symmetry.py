"""rsl_rl's symmetry extension on PPOROA (`algo.symmetry_cfg`): what it appends to a mini-batch, the
mirror loss, and the configs it refuses."""

from __future__ import annotations

import pytest
import torch
from testkit import tiny

from lasmp.config.checks import ConfigError
from lasmp.modules.obs_groups import GROUP_DETACHED_ESTIMATES


def _learner(tmp_path, epochs: int = 1, **symmetry):
    from lasmp.algo.ppo_roa import PPOROA
    from lasmp.cli.build import make_env
    from lasmp.config.train import rsl_rl_cfg

    algo = {"estimate_rollout_every": 1, "estimate_rollout_start": 0, "symmetry_cfg": symmetry}
    cfg = tiny(tmp_path, algo={"num_mini_batches": 2, "num_learning_epochs": epochs, **algo})
    env = make_env(cfg)
    rsl = rsl_rl_cfg(cfg)
    alg = PPOROA.construct_algorithm(env.get_observations(), env, rsl, cfg.device)
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(rsl["num_steps_per_env"]):
            obs, rew, dones, extras = env.step(alg.act(obs))
            alg.process_env_step(obs, rew, dones, extras)
        alg.compute_returns(obs)
    return alg, env


def test_augmentation_appends_the_mirror_images_of_a_mini_batch_with_the_estimates_of_the_mirrored_history(
    tmp_path,
):
    alg, env = _learner(tmp_path, use_data_augmentation=True)
    assert alg.get_policy().act_on_estimates
    seen = []
    augment = alg.symmetry.augment_batch

    def record(batch, n):
        augment(batch, n)
        # the estimators' own answer on the mirrored samples, now (the ROA pass moves them after PPO's)
        answer = alg.get_policy().detached_estimates(batch.observations[n:])
        seen.append((n, batch.observations.clone(), batch.actions.clone(), batch.advantages.clone(), answer))

    alg.symmetry.augment_batch = record
    loss = alg.update()
    assert len(seen) == 2 and "symmetry" in loss
    n, obs, actions, advantages, answer = seen[0]
    assert obs.batch_size[0] == actions.shape[0] == 2 * n
    original, mirrored = obs[:n], obs[n:]
    expected = env.mirror_observations(original.exclude(GROUP_DETACHED_ESTIMATES))
    for key in expected.keys():
        torch.testing.assert_close(mirrored[key], expected[key], msg=key)
    torch.testing.assert_close(actions[n:], env.mirror_actions(actions[:n]))
    torch.testing.assert_close(advantages[n:], advantages[:n])  # a mirrored step is as good as its twin
    torch.testing.assert_close(mirrored[GROUP_DETACHED_ESTIMATES], answer)
    assert not torch.allclose(mirrored[GROUP_DETACHED_ESTIMATES], original[GROUP_DETACHED_ESTIMATES])


def test_the_mirror_loss_is_a_finite_term_of_the_update_and_no_symmetry_leaves_rsl_rl_without_it(tmp_path):
    alg, _ = _learner(tmp_path / "loss", use_mirror_loss=True, mirror_loss_coeff=0.5)
    assert alg.symmetry.use_mirror_loss and not alg.symmetry.use_data_augmentation
    loss = alg.update()
    assert torch.isfinite(torch.tensor(loss["symmetry"])) and loss["symmetry"] > 0
    plain, _ = _learner(tmp_path / "plain")
    assert plain.symmetry is None and "symmetry" not in plain.update()


@pytest.mark.parametrize(
    "over, message",
    [
        ({"algo": {"symmetry_cfg": {"use_mirror_loss": True}}}, "mirror_loss_coeff"),
        ({"algo": {"symmetry_cfg": {"mirror_loss_coeff": -1.0}}}, "mirror_loss_coeff"),
        (
            {
                "task": "rough_static",
                "policy": {"command_input": True, "use_alignment": False},
                "algo": {"symmetry_cfg": {"use_data_augmentation": True}},
            },
            "no mirror maps",
        ),
    ],
)
def test_a_symmetry_config_that_cannot_work_is_refused_at_start_up(tmp_path, over, message):
    with pytest.raises(ConfigError, match=message):
        tiny(tmp_path, **over)


class _Forgetful(dict):
    """A cache that keeps nothing: every lookup misses."""

    def __setitem__(self, key, value) -> None:
        pass


def test_a_mini_batchs_mirrored_estimates_are_computed_once_per_update_and_learn_the_same_bit_for_bit(
    tmp_path,
):
    def learner(name, forgetful: bool):
        torch.manual_seed(0)
        alg, env = _learner(tmp_path / name, use_data_augmentation=True, epochs=3)
        if forgetful:
            alg._mirrored_estimates = _Forgetful()
        calls = []
        alg.get_policy().implicit_estimator.register_forward_hook(lambda *_: calls.append(1))
        loss = alg.update()
        return alg, loss, len(calls)

    cached, loss_cached, calls_cached = learner("cached", False)
    again, loss_again, calls_again = learner("again", True)
    # 2 mini-batches x 3 epochs: the mirrored estimates twice instead of six times (and the ROA pass's 2)
    assert (calls_cached, calls_again) == (2 + 2, 6 + 2)
    assert loss_cached == loss_again
    a, b = cached.get_policy().state_dict(), again.get_policy().state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
