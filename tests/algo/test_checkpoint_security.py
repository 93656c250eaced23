"""Checkpoints never run code: a hostile file through every entry point, the plain running state, and
the explicit, opt-in conversion of an older (pickled) checkpoint."""

from __future__ import annotations

import copy
import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from tensordict import TensorDict
from testkit import hostile_checkpoint, tiny

from lasmp.algo.checkpoint import PLAIN_RUN_STATE_FORMAT, CheckpointError, convert_trusted, read_checkpoint
from lasmp.cli.build import make_runner
from lasmp.cli.train import train
from lasmp.config.train import register_configs
from lasmp.envs.base_env import BaseEnv
from lasmp.io.plainstate import PlainStateError, pack, unpack

ROOT = Path(__file__).resolve().parents[2]
register_configs()


ENTRY_POINTS = {
    "play": lambda ckpt: [sys.executable, str(ROOT / "play.py"), "--checkpoint", str(ckpt), "--steps", "1"],
    "evaluate": lambda ckpt: [
        sys.executable,
        str(ROOT / "evaluate.py"),
        "--checkpoint",
        str(ckpt),
        "--num-trajectories",
        "1",
        "--batch-envs",
        "1",
    ],
    "train_resume": lambda ckpt: [
        sys.executable,
        str(ROOT / "train.py"),
        f"resume={ckpt}",
        "env.num_envs=4",
        "runner.max_iterations=1",
        f"runner.log_dir={ckpt.parent / 'run'}",
    ],
    "checkpoint_info": lambda ckpt: [sys.executable, "-m", "lasmp.algo.checkpoint", "info", str(ckpt)],
}


@pytest.mark.parametrize("entry", sorted(ENTRY_POINTS))
def test_a_hostile_checkpoint_is_refused_by_every_entry_point_without_running_its_payload(tmp_path, entry):
    marker = tmp_path / "marker"
    ckpt = hostile_checkpoint(tmp_path / "model_0.pt", marker)
    out = subprocess.run(ENTRY_POINTS[entry](ckpt), capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert not marker.exists(), f"{entry} ran the checkpoint's code"
    assert out.returncode != 0
    text = out.stdout + out.stderr
    assert "pickled Python objects" in text and "refused" in text, text[-2000:]
    assert "Traceback" not in text, text[-2000:]


def test_the_old_loader_would_have_run_the_payload(tmp_path):
    """The test above can fail: the same file, unpickled as before, does run its code."""
    marker = tmp_path / "marker"
    torch.load(hostile_checkpoint(tmp_path / "m.pt", marker), weights_only=False)
    assert marker.exists()


@pytest.mark.parametrize("task", ["moving_platform", "rough_static"])
def test_a_full_checkpoint_loads_with_weights_only_and_holds_no_project_class(tmp_path, task):
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cfg = compose(
            "config",
            overrides=[
                f"task={task}",
                "env.num_envs=4",
                "runner.max_iterations=2",
                f"runner.log_dir={tmp_path}",
                "torch_threads=1",
                "runner.save_interval=1",
                "runner.num_steps_per_env=5",
                "policy.actor_hidden_dims=[32,32,32]",
            ],
        )
    train(cfg)
    data = torch.load(tmp_path / "model_1.pt", weights_only=True)  # raises on any pickled class
    assert data["env_state"]["run"]["format"] == 3

    def walk(obj):
        if isinstance(obj, dict):
            for v in obj.values():
                walk(v)
        elif isinstance(obj, (list, tuple)):
            for v in obj:
                walk(v)
        else:
            assert isinstance(obj, (torch.Tensor, bool, int, float, str, type(None))), type(obj)

    walk(data)


@dataclasses.dataclass
class _Pair:
    a: torch.Tensor
    b: np.ndarray


def test_plain_state_round_trips_arrays_tensordicts_dataclasses_and_stateful_objects():
    td = TensorDict({"x": torch.arange(6.0).view(3, 2), "y": {"z": torch.ones(3)}}, batch_size=[3])
    live = {
        "pair": _Pair(torch.zeros(2), np.zeros(3)),
        "td": td,
        "arr": np.arange(4, dtype=np.int32),
        "none": None,
        "n": np.float64(2.5),
        "t": (1, "s"),
        "dtype": torch.float64,
    }
    saved = {
        "pair": _Pair(torch.tensor([1.0, 2.0]), np.array([3.0, 4.0, 5.0])),
        "td": td,
        "arr": live["arr"],
        "none": None,
        "n": np.float64(2.5),
        "t": (1, "s"),
        "dtype": torch.float64,
    }
    back = unpack(pack(saved), live)
    assert torch.equal(back["pair"].a, saved["pair"].a) and np.array_equal(back["pair"].b, saved["pair"].b)
    assert isinstance(back["pair"].b, np.ndarray) and back["arr"].dtype == np.int32
    assert torch.equal(back["td"]["y", "z"], td["y", "z"]) and back["td"].batch_size == td.batch_size
    assert (
        back["n"] == 2.5 and back["t"] == (1, "s") and back["dtype"] is torch.float64 and back["none"] is None
    )
    assert back["pair"] is not live["pair"]  # a copy of the live instance, not the live one changed


def test_plain_state_refuses_a_class_the_live_env_does_not_hold():
    saved = pack({"pair": _Pair(torch.zeros(1), np.zeros(1))})
    with pytest.raises(PlainStateError, match="holds a _Pair, this env nothing"):
        unpack(saved, {"pair": None})
    saved["pair"]["class"] = "os.system"
    with pytest.raises(PlainStateError, match="os.system"):
        unpack(saved, {"pair": _Pair(torch.zeros(1), np.zeros(1))})
    with pytest.raises(PlainStateError, match="cannot be stored"):
        pack({"f": open})


def test_the_converter_writes_the_running_state_format_the_envs_read():
    assert PLAIN_RUN_STATE_FORMAT == BaseEnv.RUN_STATE_FORMAT


def test_an_older_pickled_checkpoint_is_refused_with_the_convert_command_and_converts_on_trust(tmp_path):
    runner = train(tiny(tmp_path / "run", steps=5))
    env = runner.env
    data = torch.load(tmp_path / "run" / "model_1.pt", weights_only=True)
    # the format before plain state (2): the running state's objects pickled as they are
    names = env.RUN_STATE + env.TASK_STATE
    data["env_state"]["run"].update(
        format=2, sim=env.sim.get_state(), attrs=copy.deepcopy({k: getattr(env, k) for k in names})
    )
    torch.save(data, tmp_path / "old.pt")
    with pytest.raises(CheckpointError, match="convert --trust"):
        read_checkpoint(tmp_path / "old.pt")
    refused = subprocess.run(
        [
            sys.executable,
            "-m",
            "lasmp.algo.checkpoint",
            "convert",
            str(tmp_path / "old.pt"),
            str(tmp_path / "new.pt"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert refused.returncode == 2 and "--trust" in refused.stderr and not (tmp_path / "new.pt").exists()
    convert_trusted(tmp_path / "old.pt", tmp_path / "new.pt")
    fresh = make_runner(tiny(tmp_path / "fresh", steps=5), None)
    fresh.load(str(tmp_path / "new.pt"))  # the converted running state restores
    assert fresh.current_learning_iteration == 2
    assert torch.equal(fresh.env.episode_length_buf, env.episode_length_buf)
    assert np.array_equal(fresh.env.sim.get_state()["state"], env.sim.get_state()["state"])
    with pytest.raises(
        CheckpointError,
        match=r"new\.pt already exists \(a full checkpoint\): choose another OUT, or pass --force",
    ):
        convert_trusted(tmp_path / "old.pt", tmp_path / "new.pt")


@pytest.mark.parametrize(
    "saved",
    [
        {"__plain__": "ndarray", "data": 5},
        {"__plain__": "tensordict", "batch_size": [2], "data": [1, 2]},
        {"__plain__": "dataclass", "class": "_Pair", "fields": [1, 2]},
    ],
)
def test_plain_state_refuses_a_tagged_value_of_the_wrong_type_by_name(saved):
    with pytest.raises(PlainStateError, match=r"state\.x: a stored \w+ without its"):
        unpack({"x": saved}, {"x": _Pair(torch.zeros(1), np.zeros(1))})
