"""Actor-side layout of the LAS-MP policy inputs (SPEC §7-8).

The backbone b_theta is the MLP of `LasmpActor` (an rsl_rl `MLPModel`, in `policy.py`); this file
holds what defines its inputs: the observation groups, the names and selections of x_exp for the
ablations, and the alignment command rebuilt from estimates.
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

GYRO_Z_COL = 5  # o = [acc (3), gyro (3), ...]: measured yaw rate omega^B_body,z, rad/s

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

# selected x_exp columns per `explicit` option
EXPLICIT_SELECTIONS: dict[str, tuple[int, ...]] = {
    "all": tuple(range(13)),
    "no_platform": tuple(range(7)),  # contacts + body velocity
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
    v_rel = x_exp_hat[:, 7:9] - x_exp_hat[:, 4:6]
    w_rel = x_exp_hat[:, 12:13] - gyro_z.unsqueeze(-1)
    return torch.cat([v_rel, w_rel], dim=-1)
