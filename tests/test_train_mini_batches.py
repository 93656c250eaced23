"""The mini-batches of PPO's epochs: the observation groups they carry, rsl_rl's same batches in
every epoch, and the ppo_pass gathering them once."""

from __future__ import annotations

import pytest
import torch
from testkit import runner_rollout as rollout
from testkit import tiny

from lasmp.cli.build import make_runner
from lasmp.modules.obs_groups import GROUP_DETACHED_ESTIMATES, GROUP_HISTORY


@pytest.mark.parametrize(
    ("policy", "on_estimates", "history_read"),
    [({}, False, False), ({}, True, False), ({"history_input": True, "use_alignment": False}, False, True)],
)
def test_ppo_mini_batches_carry_the_history_only_where_the_actor_reads_it(
    tmp_path, policy, on_estimates, history_read
):
    runner = make_runner(tiny(tmp_path, policy=policy), None)
    alg, actor = runner.alg, runner.alg.get_policy()
    rollout(runner)
    actor.act_on_estimates = on_estimates
    seen = []
    real = actor.get_latent

    def spy(obs, *args, **kwargs):
        seen.append(set(obs.keys()))
        return real(obs, *args, **kwargs)

    actor.get_latent = spy
    alg.update_roa = lambda: {}
    alg.update()
    assert seen and all((GROUP_HISTORY in keys) == history_read for keys in seen)
    assert all((GROUP_DETACHED_ESTIMATES in keys) == on_estimates for keys in seen)
    stored = set(alg.storage.observations.keys())
    assert GROUP_HISTORY in stored and GROUP_DETACHED_ESTIMATES not in stored  # restored for the next rollout


def _batch_fields(batch) -> list[torch.Tensor]:
    obs = batch.observations
    return [obs[k] for k in sorted(obs.keys())] + [
        batch.actions,
        batch.values,
        batch.advantages,
        batch.returns,
        batch.old_actions_log_prob,
        *batch.old_distribution_params,
    ]


def test_rsl_rl_visits_the_same_mini_batches_in_every_epoch(tmp_path):
    """What `RoaRolloutStorage.ppo_pass` relies on: an rsl_rl that drew a new permutation per
    epoch would fail here rather than have its epochs silently collapse into one."""
    runner = make_runner(tiny(tmp_path), None)
    rollout(runner)
    batches = list(runner.alg.storage.mini_batch_generator(2, 3))
    assert len(batches) == 6
    for first, later in zip(batches[:2] * 2, batches[2:], strict=True):
        assert all(torch.equal(a, b) for a, b in zip(_batch_fields(first), _batch_fields(later), strict=True))
    assert not torch.equal(batches[0].actions, batches[1].actions)


def test_ppo_pass_mini_batches_gathered_once_equal_rsl_rl_s_and_are_fresh_objects(tmp_path):
    runner = make_runner(tiny(tmp_path), None)
    storage = runner.alg.storage
    rollout(runner)
    torch.manual_seed(7)
    expected = list(storage.mini_batch_generator(2, 3))
    torch.manual_seed(7)
    with storage.ppo_pass(storage.observations):
        got = list(storage.mini_batch_generator(2, 3))
    assert len(got) == len(expected) == 6 and len({id(b) for b in got}) == 6
    for a, b in zip(expected, got, strict=True):
        assert all(torch.equal(x, y) for x, y in zip(_batch_fields(a), _batch_fields(b), strict=True))
    got[0].advantages = got[0].advantages * 0.0  # PPO reassigns fields: the next epoch's batch keeps its own
    assert torch.equal(got[2].advantages, expected[2].advantages)
