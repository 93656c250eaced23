"""train.py resume=: a bad checkpoint given to resume, a bad latest checkpoint of a run, and resume
overrides that cannot take effect (refused) or can (applied and recorded)."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
from badkit import _truncated, _write, files, latest, refused, succeeded, tiny, train
from omegaconf import OmegaConf
from testkit import hostile_checkpoint

from lasmp.algo import checkpoint as ckpt_tool
from lasmp.envs.trajectories.splines import PiecewisePoly
from lasmp.io import plainstate


# -- checkpoints given to resume -----------------------------------------------------------------
def _saved(good: Path) -> dict:
    return torch.load(good, weights_only=True)


def _edit(change):
    def make(good: Path, dst: Path) -> Path:
        data = _saved(good)
        change(data)
        torch.save(data, dst)
        return dst

    return make


def _first_tensor(data, key):
    return next(iter(data[key].values()))


def _not_torch_zip(good: Path, dst: Path) -> Path:
    with zipfile.ZipFile(dst, "w") as z:
        z.writestr("notes.txt", "not a checkpoint")
    return dst


def _missing(good: Path, dst: Path) -> Path:
    return dst


def _empty_dir(good: Path, dst: Path) -> Path:
    return dst.parent


def _hostile(good: Path, dst: Path) -> Path:
    return hostile_checkpoint(dst, dst.parent.parent / "marker")


def _policy_only(good: Path, dst: Path) -> Path:
    return ckpt_tool.policy_checkpoint(good, dst)


def _nan_weight(data):
    _first_tensor(data, "actor_state_dict").view(-1)[0] = float("nan")


def _wrong_shape(data):
    key = next(iter(data["actor_state_dict"]))
    data["actor_state_dict"][key] = torch.zeros(3)


def _missing_weight(data):
    data["actor_state_dict"].pop(next(iter(data["actor_state_dict"])))


def _optimizer_mismatch(data):
    data["optimizer_state_dict"]["param_groups"][0]["params"] = [0]


def _run_state_other_size(data):
    data["env_state"]["run"]["num_envs"] = 8


def _run_state_lacking(data):
    data["env_state"]["run"]["attrs"].pop("history")


def _bad_rng(data):
    data["rng_state"]["torch"] = torch.zeros(3)


def _config_unknown_key(data):
    data["config"]["env"]["bogus"] = 1


def _nan_learning_rate(data):
    data["optimizer_state_dict"]["param_groups"][0]["lr"] = float("nan")


def _negative_learning_rate(data):
    data["optimizer_state_dict"]["param_groups"][0]["lr"] = -1e-3


def _negative_action_std(data):
    data["actor_state_dict"]["distribution.std_param"].fill_(-0.5)


def _nan_action_in_the_env_state(data):
    data["env_state"]["run"]["attrs"]["action"].view(-1)[0] = float("nan")


def _pop(key):
    return lambda data: data.pop(key)


CHECKPOINT_CASES = {
    "a missing file": (_missing, "does not exist"),
    "an empty run directory": (_empty_dir, "no checkpoint"),
    "an empty file": (_write(b""), "unreadable"),
    "a text file": (_write(b"hello, I am not a checkpoint\n" * 10), "unreadable"),
    "a zip that is not a torch file": (_not_torch_zip, "unreadable"),
    "a truncated checkpoint": (_truncated, "unreadable"),
    "a torch file holding a list": (
        lambda good, dst: torch.save([1, 2], dst) or dst,
        "not a lasmp checkpoint",
    ),
    "a dict without the format": (_edit(_pop("format")), "not a lasmp checkpoint"),
    "another format version": (
        _edit(lambda d: d.update(format="lasmp-checkpoint-v0")),
        "not a lasmp checkpoint",
    ),
    "no actor weights": (_edit(_pop("actor_state_dict")), "lacks 'actor_state_dict'"),
    "no observation layout": (_edit(_pop("obs_layout")), "lacks 'obs_layout'"),
    "no config": (_edit(_pop("config")), "lacks 'config'"),
    "no iteration": (_edit(_pop("iter")), "lacks 'iter'"),
    "an iteration that is not a number": (_edit(lambda d: d.update(iter="five")), "iter"),
    # a run continued from it would number its saves from there (model_1000000000000001.pt)
    "an iteration of 10^15": (
        _edit(lambda d: d.update(iter=10**15)),
        r"stores iteration 10+, not an iteration count",
    ),
    "a stored iteration other than its name's": (
        _edit(lambda d: d.update(iter=7)),
        r"model_1\.pt stores iteration 7, but its name says 1: it was renamed or altered",
    ),
    "a hostile payload": (_hostile, "pickled Python objects"),
    "a policy checkpoint": (_policy_only, "policy checkpoint"),
    "a NaN weight": (_edit(_nan_weight), "non-finite"),
    "another observation layout": (_edit(lambda d: d["obs_layout"].update(history=[15, 44])), "'history'"),
    "another action size": (_edit(lambda d: d.update(num_actions=8)), "actions"),
    "a weight of another shape": (_edit(_wrong_shape), "size mismatch"),
    "a missing weight": (_edit(_missing_weight), "[Mm]issing key"),
    "an optimizer of another layout": (_edit(_optimizer_mismatch), "optimizer"),
    "a running state for another number of envs": (_edit(_run_state_other_size), "resume_drop_env_state"),
    "a running state lacking a buffer": (_edit(_run_state_lacking), "running state"),
    "a corrupt random state": (_edit(_bad_rng), "random state"),
    "a config this code cannot rebuild": (_edit(_config_unknown_key), "bogus"),
    # a state a training cannot go on from: refused naming the entry, not after a step
    "a NaN learning rate in the optimizer (C_nan_lr)": (
        _edit(_nan_learning_rate),
        r"optimizer_state_dict\.param_groups\[0\]\.lr is not finite",
    ),
    "a negative learning rate": (
        _edit(_negative_learning_rate),
        r"param_groups\[0\]\.lr = -0.001 is out of range",
    ),
    "a negative action noise": (_edit(_negative_action_std), r"distribution\.std_param = .* is out of range"),
    "a NaN action in the envs' running state (C_nan_action)": (
        _edit(_nan_action_in_the_env_state),
        r"env_state\.run\.attrs\.action is not finite",
    ),
}


def _trajectory_fields(data) -> dict:
    return data["env_state"]["run"]["attrs"]["traj"]["fields"]


def _shorter_first_trajectory(data):
    """The envs' trajectories rebuilt with env 0's one knot shorter: its row NaN-padded, as rows of
    different lengths are in any run past the curriculum's first levels."""
    keys = ("knot_times_s", "knot_poses", "n_knots", "kind", "degree", "n_waypoints")
    f = {k: _trajectory_fields(data)[k]["data"].numpy() for k in keys}
    t, p, n = f["knot_times_s"].copy(), f["knot_poses"].copy(), f["n_knots"].copy()
    t[0, n[0] - 1], p[0, n[0] - 1], n[0] = np.nan, np.nan, n[0] - 1
    short = PiecewisePoly.from_knots(t, p, n, f["kind"], f["degree"], f["n_waypoints"])
    data["env_state"]["run"]["attrs"]["traj"] = plainstate.pack(short)


def _nan_inside_a_trajectory(data):
    _shorter_first_trajectory(data)
    _trajectory_fields(data)["knot_times_s"]["data"][0, 1] = float("nan")


def _inf_padding_of_knot_times(data):
    _shorter_first_trajectory(data)
    t = _trajectory_fields(data)["knot_times_s"]["data"]
    t[torch.isnan(t)] = float("inf")


CHECKPOINT_CASES.update(
    {
        "a NaN inside a trajectory's knots": (
            _edit(_nan_inside_a_trajectory),
            r"knot_times_s\.data is not finite where it is not padding",
        ),
        "a trajectory padded with +inf where its padding is NaN": (
            _edit(_inf_padding_of_knot_times),
            r"knot_times_s\.data is not finite where it is not padding",
        ),
    }
)


def test_a_checkpoint_whose_trajectories_differ_in_length_resumes_their_nan_padding_is_not_corruption(
    run_copy,
):
    _edit(_shorter_first_trajectory)(run_copy / "model_1.pt", run_copy / "model_1.pt")
    assert torch.isnan(_trajectory_fields(_saved(run_copy / "model_1.pt"))["knot_times_s"]["data"][0]).any()
    succeeded(train(tiny(f"resume={run_copy}", "runner.max_iterations=1")))
    assert (run_copy / "model_2.pt").exists()


@pytest.mark.parametrize("case", sorted(CHECKPOINT_CASES))
def test_a_bad_checkpoint_given_to_resume_is_refused_and_nothing_is_written(base_run, tmp_path, case):
    make, pattern = CHECKPOINT_CASES[case]
    bad_dir = tmp_path / "bad"
    bad_dir.mkdir()
    given = make(base_run / "model_1.pt", bad_dir / "model_1.pt")  # its name and stored iteration agree
    before = files(bad_dir)
    out = train(tiny(f"resume={given}", f"runner.log_dir={bad_dir}"))
    refused(out, pattern)
    assert files(bad_dir) == before
    assert not (tmp_path / "marker").exists()  # no payload ran


def test_a_bad_latest_checkpoint_of_a_run_is_refused_and_the_run_is_left_as_it_was(run_copy):
    (run_copy / "model_2.pt").write_bytes((run_copy / "model_1.pt").read_bytes()[:3000])
    before = files(run_copy)
    out = train(tiny(f"resume={run_copy}"))
    refused(out, "unreadable", "model_2.pt")
    assert files(run_copy) == before


# -- resume overrides ----------------------------------------------------------------------------
RESUME_REFUSED = {
    "more envs without dropping their state": (["env.num_envs=8"], "resume_drop_env_state"),
    "other actor layers": (["policy.actor_hidden_dims=[16,16,16]"], "policy.actor_hidden_dims"),
    "another activation": (["policy.activation=tanh"], "policy.activation"),
    "another initial action noise": (["policy.init_noise_std=0.7"], "policy.init_noise_std"),
    "another seed": (["seed=7"], "seed"),
    "another task": (["task=rough_static"], "task"),
    "another observation history": (["env.observations.history_length=15"], "history"),
}


@pytest.mark.parametrize("case", sorted(RESUME_REFUSED))
def test_a_resume_override_that_cannot_take_effect_is_refused_and_the_run_is_left_as_it_was(run_copy, case):
    overrides, pattern = RESUME_REFUSED[case]
    before = files(run_copy)
    out = train(tiny(*overrides, f"resume={run_copy}", f"runner.log_dir={run_copy}"))
    refused(out, pattern)
    assert files(run_copy) == before


def test_more_envs_on_resume_with_the_option_to_drop_their_state_trains_on(run_copy):
    out = train(tiny("env.num_envs=8", "resume_drop_env_state=true", f"resume={run_copy}"))
    succeeded(out)
    assert latest(run_copy).name == "model_2.pt"
    assert OmegaConf.load(run_copy / "config.yaml").env.num_envs == 8


def test_a_new_learning_rate_on_resume_is_applied_not_ignored(run_copy):
    out = train(tiny("algo.schedule=fixed", "algo.learning_rate=0.0005", f"resume={run_copy}"))
    succeeded(out)
    saved = torch.load(latest(run_copy), weights_only=True)
    assert saved["optimizer_state_dict"]["param_groups"][0]["lr"] == pytest.approx(0.0005)
    assert OmegaConf.load(run_copy / "config.yaml").algo.learning_rate == pytest.approx(0.0005)


def test_a_new_learning_rate_under_the_adaptive_schedule_is_applied_and_said(run_copy):
    out = train(tiny("algo.learning_rate=0.0005", f"resume={run_copy}"))
    succeeded(out)
    assert re.search(r"algo\.learning_rate.*0\.0005", out.text), out.text[-3000:]


def test_a_changed_reward_setting_on_resume_takes_effect_and_is_recorded(run_copy):
    out = train(tiny("env.rewards.sigma_center_m=1.0", f"resume={run_copy}"))
    succeeded(out)
    assert OmegaConf.load(run_copy / "config.yaml").env.rewards.sigma_center_m == 1.0
    assert (
        torch.load(latest(run_copy), weights_only=True)["config"]["env"]["rewards"]["sigma_center_m"] == 1.0
    )


def test_resume_with_the_run_directory_alone_continues_the_runs_own_config(run_copy):
    out = train([f"resume={run_copy}"])  # no other override: the run's 4 envs, small networks, 2 iterations
    succeeded(out)
    assert latest(run_copy).name == "model_3.pt"
    assert OmegaConf.load(run_copy / "config.yaml").env.num_envs == 4


# -- a resume from an earlier checkpoint: the advice never sends the user back and forth -----------
def test_resuming_an_earlier_checkpoint_advises_the_newest_full_one_never_a_policy_checkpoint(run_copy):
    from lasmp.algo.checkpoint import policy_checkpoint

    before = files(run_copy)
    out = train(tiny(f"resume={run_copy / 'model_0.pt'}", f"runner.log_dir={run_copy}"))
    refused(out, r"Resume from model_1\.pt, the newest full checkpoint")
    # the later checkpoint became a policy checkpoint: resuming it is refused too, so it is not advised
    policy_checkpoint(run_copy / "model_1.pt", run_copy / "policy_1.pt")
    (run_copy / "model_1.pt").unlink()
    out = train(tiny(f"resume={run_copy / 'model_0.pt'}", f"runner.log_dir={run_copy}"))
    refused(
        out,
        r"policy_1\.pt came later",
        r"policy checkpoints, which cannot resume: give runner\.log_dir=NEW_DIR",
    )
    assert "Resume from policy_1" not in out.text
    assert not (run_copy / "model_2.pt").exists() and set(files(run_copy)) - set(before) == {"policy_1.pt"}
