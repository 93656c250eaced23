"""The one place lasmp reaches below rsl_rl's public API.

rsl_rl (pyproject pins >=5.4.2,<6) offers no public seam for the things lasmp does here: build its
own actor on rsl_rl's MLP model (the model sizes its input from two hooks), replace the runner's
multi-GPU setup (rsl_rl's assumes NCCL on CUDA; lasmp also trains on CPUs over gloo), keep the
logger's episode statistics in a checkpoint (a resumed run logs the rewards an uninterrupted one
would), read the episode extras the logger gathers (lasmp prints its own progress line), and name the
file a failed write of the logger's code-state record was writing. The private or undocumented names
this takes from rsl_rl, which lasmp takes nowhere else (`tests/test_compat.py` greps lasmp for them):

- `MLPModel._get_obs_dim`, `MLPModel._get_latent_dim`: the hooks `MLPModel.__init__` calls to
  choose the observation groups and size the MLP's input (rsl_rl's own CNN and RNN models override
  them); `MLPModelCompat` hands them to `select_obs` and `backbone_input_size`.
- `OnPolicyRunner._configure_multi_gpu`: the hook `OnPolicyRunner.__init__` calls before it builds
  the learner (it sets `gpu_world_size`, `gpu_global_rank`, `gpu_local_rank`, `is_distributed` and
  `cfg["multi_gpu"]`); `OnPolicyRunnerCompat` hands it to `configure_ranks`.
- `rsl_rl.utils.logger.Logger`, a module `rsl_rl.utils` does not export, and the Logger's buffers
  `rewbuffer`, `lenbuffer` (the last 100 finished episodes' returns and lengths),
  `cur_reward_sum`, `cur_episode_length` (the running episodes') and `ep_extras` (the env's
  `extras["episode"]` of the iteration's steps): `LoggerCompat`.
- `Logger._store_code_state`, the method that writes the run's `git/<repository>.diff`, by name in
  a traceback: `raised_storing_code_state`.
- `EmpiricalNormalization`'s buffers `_var` and `_std`, by their names in a state_dict (a
  checkpoint's keys), whose ranges a resume checks: `NORMALIZER_VAR_KEY`, `NORMALIZER_STD_KEY`.

Read outside this module, as rsl_rl's own runner and logger read them: the Logger's `log_dir`,
`writer`, and the arguments it keeps (`cfg`, `num_envs`, `gpu_world_size`). The observation
normalizer's statistics are read through its public `mean` and `std`.

TensorBoard's and Hydra's private names are read in the sibling modules `lasmp/compat/tensorboard.py` and
`lasmp/compat/hydra.py`. This module sits in the lowest layer (docs/layout.md) so that both the
networks (lasmp/modules) and the learner (lasmp/algo) can import it.

`tests/test_rsl_compat.py` names each one and checks that the installed rsl_rl still has it and
still uses it as lasmp expects, so that an rsl_rl upgrade which breaks lasmp fails there first,
pointing here.
"""

from __future__ import annotations

import traceback
from collections import deque

from rsl_rl.models import MLPModel
from rsl_rl.runners import OnPolicyRunner
from rsl_rl.utils.logger import Logger
from tensordict import TensorDict

# the Logger's method that writes the run's git/<repository>.diff
_CODE_STATE_METHOD = "_store_code_state"
# the last names of EmpiricalNormalization's variance and standard deviation in its state_dict
NORMALIZER_VAR_KEY = "_var"
NORMALIZER_STD_KEY = "_std"


class MLPModelCompat(MLPModel):
    """rsl_rl's MLP model whose input hooks are a subclass's `select_obs()` (the active observation
    groups of `obs_groups[obs_set]` and the size of their concatenation, which the model normalizes)
    and `backbone_input_size()` (the size of the MLP's input). `MLPModel.__init__` calls both, in that
    order, before it builds the normalizer and the MLP."""

    def _get_obs_dim(
        self, obs: TensorDict, obs_groups: dict[str, list[str]], obs_set: str
    ) -> tuple[list[str], int]:
        return self.select_obs(obs, obs_groups, obs_set)

    def _get_latent_dim(self) -> int:
        return self.backbone_input_size()

    def select_obs(
        self, obs: TensorDict, obs_groups: dict[str, list[str]], obs_set: str
    ) -> tuple[list[str], int]:
        """rsl_rl's own choice: every group of `obs_groups[obs_set]`, each (n, d)."""
        return super()._get_obs_dim(obs, obs_groups, obs_set)

    def backbone_input_size(self) -> int:
        """rsl_rl's own size: the normalized observations alone."""
        return super()._get_latent_dim()


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


def raised_storing_code_state(err: BaseException) -> bool:
    """Whether `err` came from the logger writing its record of the code's state
    (`<log_dir>/git/<repository>.diff`, when the logging starts). Why by name: rsl_rl raises the bare
    OSError of its write, which names no file, and gives no other sign of where it was; the
    traceback's frames are the one record of it."""
    return any(frame.name == _CODE_STATE_METHOD for frame in traceback.extract_tb(err.__traceback__))
