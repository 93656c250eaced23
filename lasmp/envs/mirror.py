"""The sagittal mirror (left <-> right) as signed permutations of a quantity's columns.

A frame's y axis flips under the mirror. So in any frame whose x-z plane is the mirror plane (the
trunk frame; the world and platform frames, once the mirrored world's y is negated):
- a vector (position, velocity, acceleration, force) keeps x and z and negates y;
- a pseudo-vector (angular velocity) negates x and z and keeps y;
- ZYX Euler angles negate roll and yaw and keep pitch;
- per-leg quantities swap left and right legs, and a joint angle also takes its joint's sign
  (`lasmp.robots.a1.MIRROR_JOINTS`, `MIRROR_JOINT_SIGNS`).

`Mirror` maps columns: out = x[..., perm] * sign + offset. The offset is for an absolute quantity
measured from an origin the mirror moves: the trunk's CoM shift, whose nominal place lies 2.2 mm left
of the trunk's x-z plane (the published inertials), mirrors to -shift_y - 2 * 2.2 mm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from lasmp.robots import a1


@dataclass(frozen=True)
class Mirror:
    """A signed permutation with an offset on the last dimension: x -> x[..., perm] * sign + offset."""

    perm: tuple[int, ...]
    sign: tuple[float, ...]
    offset: tuple[float, ...]

    def __post_init__(self):
        n = len(self.perm)
        if sorted(self.perm) != list(range(n)) or len(self.sign) != n or len(self.offset) != n:
            raise ValueError(f"not a signed permutation of {n} columns: {self}")

    def __len__(self) -> int:
        return len(self.perm)

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        if x.shape[-1] != len(self):
            raise ValueError(f"the mirror maps {len(self)} columns, got a tensor of shape {tuple(x.shape)}")
        sign = torch.as_tensor(self.sign, dtype=x.dtype, device=x.device)
        out = x[..., list(self.perm)] * sign
        if any(self.offset):
            out = out + torch.as_tensor(self.offset, dtype=x.dtype, device=x.device)
        return out


def block(
    perm: Sequence[int] = (), sign: Sequence[float] = (), offset: Sequence[float] | None = None
) -> Mirror:
    return Mirror(tuple(perm), tuple(float(s) for s in sign), tuple(offset or (0.0,) * len(perm)))


def keep(n: int) -> Mirror:
    """n columns the mirror leaves alone (masses, friction, heights)."""
    return block(range(n), (1.0,) * n)


VECTOR = block((0, 1, 2), (1, -1, 1))
PSEUDO_VECTOR = block((0, 1, 2), (-1, 1, -1))
EULER_ZYX = block((0, 1, 2), (-1, 1, -1))  # roll, pitch, yaw
ROLL_PITCH = block((0, 1), (-1, 1))
PLANAR_TWIST = block((0, 1, 2), (1, -1, -1))  # [v_x, v_y, omega_z]: a velocity command, u_aln
LEGS = block(a1.MIRROR_LEGS, (1.0,) * 4)  # per-leg flags: contacts
JOINT_ANGLES = block(a1.MIRROR_JOINTS, a1.MIRROR_JOINT_SIGNS)  # angles, rates, torques, actions
JOINT_GAINS = block(a1.MIRROR_JOINTS, (1.0,) * 12)  # per-joint Kp, Kd


def com_shift(nominal_com_y_m: float) -> Mirror:
    """The trunk's CoM shift (3) from its nominal place, whose y is `nominal_com_y_m`."""
    return block((0, 1, 2), (1, -1, 1), (0.0, -2.0 * nominal_com_y_m, 0.0))


def concat(*parts: Mirror) -> Mirror:
    """The mirror of columns laid out part after part."""
    perm, sign, offset, start = [], [], [], 0
    for m in parts:
        perm += [start + i for i in m.perm]
        sign += m.sign
        offset += m.offset
        start += len(m)
    return block(perm, sign, offset)
