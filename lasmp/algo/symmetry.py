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
