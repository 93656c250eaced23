"""runner.logger: tensorboard (default), wandb or neptune through rsl_rl's writers (docs/logging.md).

A tiny training into an offline W&B run (and an offline Neptune run where `neptune` is installed)
must hold every scalar our OneLineLogger writes, at the iteration it was written, with the value the
TensorBoard files (which those writers also write) hold. Bad choices fail at start-up, naming the field.
"""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path

import pytest
from omegaconf import OmegaConf
from rsl_rl.utils.utils import resolve_class
from testkit import tiny

import lasmp.cli.build
import lasmp.cli.train
import lasmp.config.train
from lasmp.algo.checkpoint import CheckpointError, read_checkpoint
from lasmp.cli.train import train
from lasmp.config.checkpoint import checkpoint_cfg
from lasmp.config.checks import ConfigError
from lasmp.config.train import register_configs, rsl_rl_cfg
from lasmp.eval.curves import read_scalars

register_configs()
# scalars OneLineLogger writes every iteration (the episode extras come on top)
# episodes of 0.3 s (15 policy steps) end in every 24-step iteration, so every iteration logs an
# episode's mean reward, whatever the initial action noise
SHORT_EPISODES = {"trajectory": {"duration_s": 0.3}}
EVERY_ITERATION = {
    "Loss/learning_rate",
    "Policy/mean_std",
    "Perf/total_fps",
    "Train/mean_reward",
    "Loss/roa_exp",
}


def tensorboard_scalars(run_dir: Path) -> dict[str, dict[int, float]]:
    return {
        tag: dict(zip(it.tolist(), v.tolist(), strict=True)) for tag, (it, v) in read_scalars(run_dir).items()
    }


def assert_same_scalars(logged: dict[int, dict[str, float]], run_dir: Path, key=lambda tag: tag) -> None:
    """`logged` ({step: {key: value}}) holds every TensorBoard scalar of `run_dir` at its step."""
    tb = tensorboard_scalars(run_dir)
    assert EVERY_ITERATION <= set(tb)
    assert sorted(logged) == [0, 1]
    for tag, series in tb.items():
        for step, value in series.items():
            assert logged[step][key(tag)] == pytest.approx(value, rel=1e-6, abs=1e-7), (tag, step)


# -- choosing and checking -----------------------------------------------------------------------
def test_unknown_logger_is_refused_at_start_up_naming_the_field(tmp_path, monkeypatch):
    def no_env(*_):
        raise AssertionError("an env was built before the config was checked")

    monkeypatch.setattr(lasmp.cli.build, "make_env", no_env)
    run = tmp_path / "run"
    with pytest.raises(
        ConfigError, match=r"runner\.logger must be one of tensorboard \| wandb \| neptune, got 'mlflow'"
    ):
        train(tiny(run, precision="float32", runner={"logger": "mlflow"}))
    assert not run.exists()


def test_missing_package_or_credentials_are_refused_naming_the_fix(tmp_path, monkeypatch):
    monkeypatch.setattr(lasmp.config.train, "_installed", lambda package: False)
    for name in ("wandb", "neptune"):
        with pytest.raises(
            ConfigError,
            match=re.escape(f"runner.logger={name} needs the {name} package")
            + ".*"
            + re.escape(f'pip install -e ".[{name}]"'),
        ):
            tiny(tmp_path, precision="float32", runner={"logger": name})
    monkeypatch.setattr(lasmp.config.train, "_installed", lambda package: True)
    monkeypatch.delenv("NEPTUNE_API_TOKEN", raising=False)
    monkeypatch.setenv("NEPTUNE_USERNAME", "someone")
    with pytest.raises(ConfigError, match="runner.logger=neptune needs NEPTUNE_API_TOKEN set"):
        tiny(tmp_path, precision="float32", runner={"logger": "neptune"})
    with pytest.raises(ConfigError, match="runner.wandb_project must name a project"):
        tiny(tmp_path, precision="float32", runner={"logger": "wandb", "wandb_project": ""})


def test_rsl_rl_gets_the_dict_form_of_its_writers(tmp_path, monkeypatch):
    from rsl_rl.utils import NeptuneLogWriter, WandbLogWriter

    assert rsl_rl_cfg(tiny(tmp_path, precision="float32"))["logger"] == "tensorboard"
    monkeypatch.setattr(lasmp.config.train, "_installed", lambda package: True)
    monkeypatch.setenv("NEPTUNE_API_TOKEN", "token")
    monkeypatch.setenv("NEPTUNE_USERNAME", "someone")
    for name, writer in (("wandb", WandbLogWriter), ("neptune", NeptuneLogWriter)):
        entry = rsl_rl_cfg(
            tiny(tmp_path, precision="float32", runner={"logger": name, f"{name}_project": "p"})
        )["logger"]
        assert entry == {"class_name": writer.__name__, "project_name": "p"}
        assert resolve_class(entry) == (writer, {"project_name": "p"})


# -- W&B, offline ---------------------------------------------------------------------------------
@pytest.fixture
def offline_wandb(tmp_path, monkeypatch):
    """W&B offline, every file of it under tmp_path/wandb; yields the folder that holds the runs."""
    wandb = pytest.importorskip("wandb")
    root = tmp_path / "wandb"
    root.mkdir()
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_SILENT", "true")
    monkeypatch.setenv("WANDB_DIR", str(root))
    for var in ("WANDB_CONFIG_DIR", "WANDB_CACHE_DIR", "WANDB_DATA_DIR", "WANDB_ARTIFACT_DIR"):
        monkeypatch.setenv(var, str(root / var.lower()))
    for var in ("WANDB_USERNAME", "WANDB_ENTITY", "WANDB_PROJECT", "WANDB_RUN_ID", "WANDB_RESUME"):
        monkeypatch.delenv(var, raising=False)
    yield root / "wandb"
    if wandb.run is not None:  # a failed training left it open
        wandb.finish()


def wandb_records(path: Path):
    """The protobuf records of an offline run's .wandb file: a LevelDB-style log (wandb's own reader
    went into its Go core): a 7-byte file header, then in 32 KiB blocks chunks of [crc32c u32, length
    u16, type u8] + data; type 1 a whole record, 2/3/4 its first/middle/last part."""
    from wandb.proto import wandb_internal_pb2

    raw, block, header = path.read_bytes(), 32768, 7
    assert raw[:4] == b":W&B"
    pos, parts = header, b""
    while pos + header <= len(raw):
        left = block - pos % block
        if left < header:  # the block's tail is padding
            pos += left
            continue
        _, length, kind = struct.unpack("<IHB", raw[pos : pos + header])
        data, pos = raw[pos + header : pos + header + length], pos + header + length
        parts = data if kind in (1, 2) else parts + data
        if kind in (1, 4):
            record = wandb_internal_pb2.Record()
            record.ParseFromString(parts)
            yield record


def test_wandb_offline_run_holds_config_and_every_scalar(tmp_path, offline_wandb, monkeypatch):
    run = tmp_path / "run"
    train(
        tiny(
            run,
            precision="float32",
            runner={"logger": "wandb", "wandb_project": "lasmp-test"},
            env=SHORT_EPISODES,
        )
    )

    (run_dir,) = offline_wandb.glob("offline-run-*")
    (log,) = run_dir.glob("run-*.wandb")
    records = list(wandb_records(log))
    kinds = [r.WhichOneof("record_type") for r in records]
    assert "exit" in kinds  # the writer finished the run
    (info,) = [r.run for r in records if r.HasField("run")]
    assert (info.project, info.display_name) == ("lasmp-test", "run")  # the run is named after its log dir
    config = {
        item.key: json.loads(item.value_json)
        for r in records
        if r.HasField("config")
        for item in r.config.update
    }
    assert config["train_cfg"]["logger"] == {"class_name": "WandbLogWriter", "project_name": "lasmp-test"}
    assert config["env_cfg"]["num_envs"] == 4
    history: dict[int, dict[str, float]] = {}
    for r in records:
        if r.HasField("history"):
            row = {i.key or "/".join(i.nested_key): json.loads(i.value_json) for i in r.history.item}
            history[int(row["_step"])] = row
    assert_same_scalars(history, run)

    # play and evaluate rebuild the run without wandb; resuming it with wandb gone says what to install
    monkeypatch.setattr(lasmp.config.train, "_installed", lambda package: False)
    data = read_checkpoint(str(run / "model_1.pt"), "cpu")
    assert checkpoint_cfg(data, num_envs=2, seed=0).runner.logger == "tensorboard"
    with pytest.raises(CheckpointError, match=re.escape("runner.logger=wandb needs the wandb package")):
        train(OmegaConf.create({"resume": str(run), "runner": {"max_iterations": 1}}), explicit=set())


# -- Neptune, offline (where the neptune extra is installed) ----------------------------------------
def test_neptune_offline_run_holds_every_scalar(tmp_path, monkeypatch):
    pytest.importorskip("neptune")
    root = tmp_path / "neptune"
    monkeypatch.setenv("NEPTUNE_MODE", "offline")
    monkeypatch.setenv("NEPTUNE_DATA_DIRECTORY", str(root))
    monkeypatch.setenv("NEPTUNE_API_TOKEN", "ANONYMOUS")  # rsl_rl's writer wants both; offline uses neither
    monkeypatch.setenv("NEPTUNE_USERNAME", "lasmp-test")
    run = tmp_path / "run"
    train(tiny(run, precision="float32", runner={"logger": "neptune"}, env=SHORT_EPISODES))

    (log,) = root.glob("offline/run__*/data-*.log")
    logged: dict[int, dict[str, float]] = {}
    for line in log.read_text().splitlines():
        op = json.loads(line)["obj"]
        if op["type"] == "LogFloats":
            for v in op["values"]:
                if v["step"] is not None:
                    logged.setdefault(int(v["step"]), {})["/".join(op["path"])] = v["value"]
    assert_same_scalars(logged, run, key=lambda tag: tag.strip("/"))  # Neptune drops a leading '/'
