"""What training prints (ours): one line per network instead of rsl_rl's printout of every layer,
then one progress line per iteration, with the TensorBoard scalars as rsl_rl's logger writes them.

Iterations are numbered from 0 everywhere, as the checkpoint files are: `it 34/999` is iteration 34
of a command whose last is 999, and when saved it is `model_34.pt`. A field with nothing to show yet
reads "\u2013": the reward until an episode has ended, the ETA until an iteration after the first
(which compiles and warms up) is timed.
"""

from __future__ import annotations

import contextlib
import datetime
import io
import re
import statistics
from collections.abc import Callable, Iterator

from lasmp.compat.rsl_rl import LoggerCompat

NONE_YET = "\u2013"  # a progress field with no value yet


class OneLineLogger(LoggerCompat):
    """TensorBoard scalars as rsl_rl's logger writes them, but one terminal line per iteration."""

    # this iteration's env-steps whose physics faulted (the runner sets it)
    iteration_faults: int | None = None
    _timed_s, _timed = 0.0, 0  # the seconds and the count of this command's iterations after its first

    def log(
        self,
        it,
        start_it,
        total_it,
        collect_time,
        learn_time,
        loss_dict,
        learning_rate,
        action_std,
        rnd_weight,
        **kwargs,
    ) -> None:
        self._log(it, start_it, total_it, collect_time, learn_time, loss_dict, learning_rate, action_std)

    def _log(
        self, it, start_it, total_it, collect_time, learn_time, loss_dict, learning_rate, action_std
    ) -> None:
        if self.writer is None:
            return
        steps = self.cfg["num_steps_per_env"] * self.num_envs * self.gpu_world_size  # all ranks' env-steps
        extras: dict[str, float] = {}
        episodes = self.take_episode_extras()
        reported = dict.fromkeys(k for ep in episodes for k in ep)  # a rate over an empty window too
        for key in reported:
            values = [float(ep[key]) for ep in episodes if key in ep]
            values = [v for v in values if v == v]  # nan: a rate over an empty window
            if values:
                extras[key] = statistics.fmean(values)
                self.writer.add_scalar(key, extras[key], it)
        for key, value in loss_dict.items():
            self.writer.add_scalar(key if "/" in key else f"Loss/{key}", value, it)
        self.writer.add_scalar("Loss/learning_rate", learning_rate, it)
        self.writer.add_scalar("Policy/mean_std", action_std.mean().item(), it)
        fps = steps / (collect_time + learn_time)
        self.writer.add_scalar("Perf/total_fps", fps, it)
        self.writer.add_scalar("Perf/collection_time", collect_time, it)
        self.writer.add_scalar("Perf/learning_time", learn_time, it)
        reward = f"{NONE_YET:>8}"  # until an episode has ended
        returns, lengths = self.finished_episodes()
        if returns:
            mean_reward = statistics.fmean(returns)
            reward = f"{mean_reward:8.2f}"
            self.writer.add_scalar("Train/mean_reward", mean_reward, it)
            self.writer.add_scalar("Train/mean_episode_length", statistics.fmean(lengths), it)
        fields = [f"it {it}/{total_it - 1}", f"{fps:,.0f} steps/s", f"reward {reward}"]
        for key, label, fmt in (
            ("Episode/success_rate", "success", ".2f"),
            ("Curriculum/level", "level", ".0f"),
        ):
            if key in extras:
                fields.append(f"{label} {extras[key]:{fmt}}")
            elif key in reported:  # the task reports it, with no value yet: its column stays in place
                fields.append(f"{label} {NONE_YET:>4}")
        if "roa_exp" in loss_dict:
            fields.append(f"L_exp {loss_dict['roa_exp']:.4f}")
        if self.iteration_faults is not None:
            fields.append(f"faults {self.iteration_faults}")
        fields.append(f"ETA {self._eta(it, start_it, total_it, collect_time + learn_time)}")
        print(" | ".join(fields), flush=True)

    def _eta(self, it: int, start_it: int, total_it: int, seconds: float) -> str:
        """The time left, from the mean time of this command's iterations after its first: the first
        compiles the networks and warms up, and can take many times as long as the rest. NONE_YET
        until such an iteration is done."""
        if it == start_it:
            self._timed_s, self._timed = 0.0, 0
            return NONE_YET
        self._timed_s, self._timed = self._timed_s + seconds, self._timed + 1
        return str(datetime.timedelta(seconds=int(self._timed_s / self._timed * (total_it - 1 - it))))


def network_line(name: str, model, obs) -> str:
    """One line for a network: its observation groups with their shapes, its MLP's input and output
    sizes, its parameter count."""
    groups = ", ".join(f"{g} {'x'.join(map(str, obs[g].shape[1:]))}" for g in model.obs_groups)
    layers = [m for m in model.mlp.modules() if hasattr(m, "in_features")]
    count = sum(p.numel() for p in model.parameters())
    return (
        f"{name}: {type(model).__name__}({groups}), MLP {layers[0].in_features} -> "
        f"{layers[-1].out_features}, {count:,} parameters"
    )


_OBS_SETS = re.compile(r"-{80}\nResolved observation sets: \n(?:\t .*\n)*-{80}\n")


@contextlib.contextmanager
def without_network_printout(learner: Callable[[], object | None]) -> Iterator[None]:
    """Around rsl_rl's build of the learner: print what it printed, less its resolved observation
    sets and its networks layer by layer (`network_line` says each in a line); anything else it
    printed stays. `learner()`: the learner built, None if the build failed (all is printed)."""
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed):
            yield
    finally:
        text, alg = printed.getvalue(), learner()
        if alg is not None:
            for title, model in (("Actor", alg.get_policy()), ("Critic", alg.critic)):
                text = text.replace(f"{title} Model: {model}\n", "", 1)
            text = _OBS_SETS.sub("", text, count=1)
        print(text, end="", flush=True)
