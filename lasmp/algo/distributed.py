"""Data-parallel training over torch.distributed, as `torchrun --nproc_per_node=K train.py ...` starts it.

Each rank steps its own `env.num_envs` envs (seed + rank: its own physics, trajectories and
curriculum draws) and runs rsl_rl's multi-GPU learner path: parameters broadcast at the start,
gradients averaged every mini-batch, the adaptive learning rate taken from rank 0, the observation
normalizers' statistics all-reduced. What rsl_rl does not cover, lasmp adds: the ROA pass's
gradients (`PPOROA.update_roa`), one shared curriculum (`SharedCurriculum`), every rank's envs'
running state in rank 0's checkpoints, and one stop iteration for a signal sent to any rank.
A rank that loses the others (one killed or crashed: gloo's "Connection closed by peer") ends with
one message naming the run's newest checkpoint and the command that resumes from it
(`lasmp.cli.train_failures.RankLost`), not with the collective's traceback.

Backends: NCCL for a learner on CUDA (`device=cuda` means each rank's `cuda:LOCAL_RANK`), gloo on a
CPU. rsl_rl's own setup hard-codes NCCL and CUDA; `LasmpRunner` replaces it with `setup`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import torch
import torch.distributed as dist


@dataclass(frozen=True)
class Ranks:
    """This process's place in the job (torchrun's WORLD_SIZE, RANK, LOCAL_RANK; 1, 0, 0 alone)."""

    world_size: int = 1
    rank: int = 0
    local_rank: int = 0

    @property
    def distributed(self) -> bool:
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def ranks_from_env() -> Ranks:
    """The job's ranks from torchrun's environment variables, checked."""
    try:
        ranks = Ranks(
            int(os.getenv("WORLD_SIZE", "1")), int(os.getenv("RANK", "0")), int(os.getenv("LOCAL_RANK", "0"))
        )
    except ValueError as err:
        raise ValueError(f"WORLD_SIZE, RANK and LOCAL_RANK must be integers: {err}") from None
    if (
        ranks.world_size < 1
        or not 0 <= ranks.rank < ranks.world_size
        or not 0 <= ranks.local_rank < ranks.world_size
    ):
        raise ValueError(f"inconsistent torchrun ranks: {ranks}")
    return ranks


def rank_device(device: str, ranks: Ranks) -> str:
    """The learner's device of this rank: `cuda` becomes `cuda:LOCAL_RANK` in a data-parallel job."""
    if not ranks.distributed or not device.startswith("cuda"):
        return device
    if device not in ("cuda", f"cuda:{ranks.local_rank}"):
        raise ValueError(
            f"device={device} in a torchrun job: give device=cuda (each rank uses cuda:LOCAL_RANK)"
        )
    return f"cuda:{ranks.local_rank}"


def setup(ranks: Ranks, device: str) -> None:
    """Join the job's process group (NCCL on CUDA, gloo on a CPU), once."""
    if not ranks.distributed or dist.is_initialized():
        return
    cuda = device.startswith("cuda")
    if cuda:
        torch.cuda.set_device(int(device.split(":")[1]))
    dist.init_process_group(backend="nccl" if cuda else "gloo", rank=ranks.rank, world_size=ranks.world_size)


def collective_device(device: str) -> str:
    """Where a collective's tensors must live: NCCL needs CUDA tensors, gloo takes CPU ones."""
    return device if dist.get_backend() == "nccl" else "cpu"


def any_rank(flag: int, device: str) -> int:
    """The largest of every rank's `flag` (e.g. a signal number, 0 for none): one answer for all."""
    t = torch.tensor([int(flag)], dtype=torch.int64, device=collective_device(device))
    dist.all_reduce(t, op=dist.ReduceOp.MAX)
    return int(t.item())


def gather_to_main(obj):
    """Every rank's `obj`, as a list in rank order on rank 0 (None on the others). Objects travel
    pickled between this job's own processes; nothing pickled reaches a checkpoint."""
    out = [None] * dist.get_world_size() if dist.get_rank() == 0 else None
    dist.gather_object(obj, out, dst=0)
    return out


def scatter_from_main(objs):
    """Rank k receives objs[k] (objs given on rank 0 only)."""
    out = [None]
    dist.scatter_object_list(out, objs if dist.get_rank() == 0 else None, src=0)
    return out[0]


def broadcast_from_main(obj):
    """Rank 0's `obj` on every rank (pickled between this job's own processes)."""
    out = [obj]
    dist.broadcast_object_list(out, src=0)
    return out[0]


def local_world_size() -> int:
    """How many of the job's processes run on this machine (torchrun's LOCAL_WORLD_SIZE; 1 alone)."""
    try:
        return max(int(os.getenv("LOCAL_WORLD_SIZE", "1")), 1)
    except ValueError:
        return 1


# how gloo and NCCL word a peer that went away (torch.distributed raises them as RuntimeError or its
# DistBackendError subclass)
PEER_LOST = (
    "Connection closed by peer",
    "Connection reset by peer",
    "Broken pipe",
    "NCCL communicator was aborted",
)


def is_peer_lost(err: BaseException) -> bool:
    """True when a collective failed because another rank of the job is gone (killed, crashed)."""
    return isinstance(err, RuntimeError) and any(words in str(err) for words in PEER_LOST)


def teardown() -> None:
    """Leave the process group (a job's processes each call it once, at the end)."""
    if dist.is_available() and dist.is_initialized():
        dist.destroy_process_group()
