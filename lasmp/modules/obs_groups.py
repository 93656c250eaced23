"""The layout of the policy's observation groups, as the actor reads them (docs/method.md, Inputs and Networks).

The group names, the columns of o and x_exp the actor picks, the x_exp selections of the
ablations, and the alignment command rebuilt from x_exp estimates. The envs write these groups
(`lasmp/envs/robot.py`: o; `lasmp/envs/moving_platform/env.py`: the others); the actor is
`LasmpActor` in `policy.py`.
"""

from __future__ import annotations

import torch

# observation groups (see lasmp/envs/moving_platform/env.py)
GROUP_OBS = "policy"
GROUP_HISTORY = "history"
GROUP_EXPLICIT = "priv_explicit"
GROUP_IMPLICIT = "priv_implicit"
GROUP_ALIGNMENT = "alignment"
GROUP_COMMAND = "command"  # a velocity command [v_x, v_y, omega_z] in B (rough_static task)
# not an env group: the estimates an iteration on the estimates acts on, added to the stored rollout
# for its PPO update by PPOROA (LasmpActor.detached_estimates)
GROUP_DETACHED_ESTIMATES = "detached_estimates"

# o = [acc (3), gyro (3), ...] (lasmp/envs/robot.py: proprioception): measured yaw rate omega^B_body,z, rad/s
GYRO_Z_COL = 5

# x_exp = [contacts (4), v_body_b (3) m/s, v_plf_b (3) m/s, omega_plf_b (3) rad/s]
X_EXP_NAMES: tuple[str, ...] = (
    "contact_FR",
    "contact_FL",
    "contact_RR",
    "contact_RL",
    "v_body_x",
    "v_body_y",
    "v_body_z",
    "v_plf_x",
    "v_plf_y",
    "v_plf_z",
    "omega_plf_x",
    "omega_plf_y",
    "omega_plf_z",
)
U_ALN_NAMES: tuple[str, ...] = ("u_aln_vx", "u_aln_vy", "u_aln_wz")


# Named column ranges of x_exp (n, 13).
def v_body_xy(x_exp: torch.Tensor) -> torch.Tensor:
    """(n, 2) trunk velocity x, y in B, m/s."""
    return x_exp[:, 4:6]


def v_plf_xy(x_exp: torch.Tensor) -> torch.Tensor:
    """(n, 2) velocity of the platform point under the trunk, x, y in B, m/s."""
    return x_exp[:, 7:9]


def omega_plf_z(x_exp: torch.Tensor) -> torch.Tensor:
    """(n, 1) platform yaw rate in B, rad/s."""
    return x_exp[:, 12:13]


# selected x_exp columns per `explicit` option
EXPLICIT_SELECTIONS: dict[str, tuple[int, ...]] = {
    "all": tuple(range(len(X_EXP_NAMES))),
    "no_platform": tuple(range(X_EXP_NAMES.index("v_plf_x"))),  # contacts + body velocity
    "none": (),
}


def explicit_indices(explicit: str) -> tuple[int, ...]:
    """x_exp columns kept by the `explicit` option; ValueError for an unknown option."""
    if explicit not in EXPLICIT_SELECTIONS:
        raise ValueError(f"explicit must be one of {sorted(EXPLICIT_SELECTIONS)}, got {explicit!r}")
    return EXPLICIT_SELECTIONS[explicit]


def alignment_from_estimates(x_exp_hat: torch.Tensor, gyro_z: torch.Tensor) -> torch.Tensor:
    """u_aln_hat = [v_plf_xy - v_body_xy, omega_plf_z - gyro_z] from a full (n, 13) x_exp estimate
    in raw units (m/s, rad/s) and the measured yaw rate gyro_z (n,) rad/s."""
    v_rel = v_plf_xy(x_exp_hat) - v_body_xy(x_exp_hat)
    w_rel = omega_plf_z(x_exp_hat) - gyro_z.unsqueeze(-1)
    return torch.cat([v_rel, w_rel], dim=-1)
