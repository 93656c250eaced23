"""rsl_rl's symmetry extension (`algorithm.symmetry_cfg`) on our envs: the augmentation function it
calls, and how PPOROA mirrors the estimates an iteration on the estimates acted on.

An env that supports the mirror has `mirror_observations(obs) -> obs` and `mirror_actions(a) -> a`
(the moving-platform task: lasmp/envs/moving_platform/mirror.py). rsl_rl appends the mirrored samples
to each PPO mini-batch (data augmentation) and/or penalizes the policy for disagreeing with its own
mirror image (the mirror loss). Mittal et al., "Symmetry Considerations for Learning Task Symmetric
Robot Policies", ICRA 2024.
"""

from __future__ import annotations

import torch
from rsl_rl.extensions.symmetry import Symmetry


def supports_mirror(env_or_class) -> bool:
    """Whether an env (or env class) has the mirror maps the augmentation needs."""
    return all(
        callable(getattr(env_or_class, name, None)) for name in ("mirror_observations", "mirror_actions")
    )


def mirror_augment(env, obs=None, actions=None):
    """rsl_rl's `data_augmentation_func`: the samples followed by their mirror images (None stays None)."""
    obs_out = None if obs is None else torch.cat([obs, env.mirror_observations(obs)])
    actions_out = None if actions is None else torch.cat([actions, env.mirror_actions(actions)])
    return obs_out, actions_out


class MirrorAugmentation(Symmetry):
    """rsl_rl's symmetry extension, whose mirror loss, when it only logs (augmentation on, mirror loss
    off), is read off the update's own forward pass over the augmented mini-batch.

    rsl_rl computes that logged loss with a second forward pass of the actor over the whole augmented
    mini-batch (`Symmetry.compute_loss`): a fifth of the PPO update's time with nothing learnt from it
    (bench/train_iteration.py, docs/performance.md). The actor's action means over that mini-batch are
    the means its distribution already holds from the forward pass PPO has just made on the same
    samples, with the same parameters: the loss is the same, its gradient none in either case."""

    def compute_loss(self, actor, batch, original_batch_size: int) -> torch.Tensor:
        if self.use_mirror_loss or not self.use_data_augmentation:
            return super().compute_loss(actor, batch, original_batch_size)
        with torch.no_grad():
            mean = actor.output_mean
            _, mirrored = self.data_augmentation_func(
                env=self.env, obs=None, actions=mean[:original_batch_size]
            )
            return torch.nn.functional.mse_loss(mean[original_batch_size:], mirrored[original_batch_size:])
