"""The one place lasmp's learner reaches below rsl_rl's public API.

rsl_rl (pyproject pins >=5.4.2,<6) offers no public seam for three things lasmp does: replace the
runner's multi-GPU setup (rsl_rl's assumes NCCL on CUDA; lasmp also trains on CPUs over gloo), keep
the logger's episode statistics in a checkpoint (a resumed run logs the rewards an uninterrupted one
would), and read the episode extras the logger gathers (lasmp prints its own progress line). The
private or undocumented names this takes from rsl_rl, which the learner takes nowhere else:

- `OnPolicyRunner._configure_multi_gpu`: the hook `OnPolicyRunner.__init__` calls before it builds
  the learner (it sets `gpu_world_size`, `gpu_global_rank`, `gpu_local_rank`, `is_distributed` and
  `cfg["multi_gpu"]`); `OnPolicyRunnerCompat` hands it to `configure_ranks`.
- `rsl_rl.utils.logger.Logger`, a module `rsl_rl.utils` does not export, and the Logger's buffers
  `rewbuffer`, `lenbuffer` (the last 100 finished episodes' returns and lengths),
  `cur_reward_sum`, `cur_episode_length` (the running episodes') and `ep_extras` (the env's
  `extras["episode"]` of the iteration's steps): `LoggerCompat`.

Read outside this module, as rsl_rl's own runner and logger read them: the Logger's `log_dir`,
`writer`, and the arguments it keeps (`cfg`, `num_envs`, `gpu_world_size`).

`tests/algo/test_rsl_compat.py` names each one and checks that the installed rsl_rl still has it,
so that an rsl_rl upgrade which breaks lasmp fails there first, pointing here.
"""

from __future__ import annotations

from collections import deque

from rsl_rl.runners import OnPolicyRunner
from rsl_rl.utils.logger import Logger


class OnPolicyRunnerCompat(OnPolicyRunner):
    """rsl_rl's runner whose multi-GPU setup is a subclass's `configure_ranks()`: it must set
    `gpu_world_size`, `gpu_global_rank`, `gpu_local_rank`, `is_distributed` and `cfg["multi_gpu"]`
    (rsl_rl's learner config: None, or the ranks as a dict), as rsl_rl's own setup does."""

    def _configure_multi_gpu(self) -> None:
        self.configure_ranks()


class LoggerCompat(Logger):
    """rsl_rl's logger with the episode statistics it keeps, read and restored under our names."""

    def finished_episodes(self) -> tuple[deque, deque]:
        """The returns and the lengths of the last finished episodes (at most 100 each)."""
        return self.rewbuffer, self.lenbuffer

    def take_episode_extras(self) -> list[dict]:
        """The env's per-episode extras gathered since the last call, which the logger then forgets."""
        extras = list(self.ep_extras)
        self.ep_extras.clear()
        return extras

    def episode_log_state(self) -> dict:
        """The running episode sums and the windows of finished episodes: without them the first
        rewards logged after a resume would count only the steps since the resume."""
        return {
            "reward_sum": self.cur_reward_sum.cpu(),
            "length": self.cur_episode_length.cpu(),
            "rewards": list(self.rewbuffer),
            "lengths": list(self.lenbuffer),
        }

    def load_episode_log_state(self, saved: dict) -> None:
        """Go on from `episode_log_state`'s record."""
        self.cur_reward_sum.copy_(saved["reward_sum"])
        self.cur_episode_length.copy_(saved["length"])
        self.rewbuffer.extend(saved["rewards"])
        self.lenbuffer.extend(saved["lengths"])
