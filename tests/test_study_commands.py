"""How scripts/study.py runs and records its commands: each logged with its time and commit before
it runs, a failed training or a Ctrl-C ending the study with the command's own status, and a
recorded run keeping its light policy beside its config and learning curve."""

from __future__ import annotations

import shlex
import subprocess
import sys

import pytest
import torch
from testkit import ROOT, Study


def test_each_command_is_logged_with_its_time_and_commit_before_it_runs(study, tmp_path):
    log = tmp_path / "runs" / "study" / "lasmp" / "seed0.commands"
    cmd = [sys.executable, "-c", "open('ran', 'w')"]
    study.real_execute(cmd, log)
    header, command = log.read_text().splitlines()
    assert header.startswith("# 20") and header.endswith(", at no commit, nice -n 10")  # tmp_path: no git
    assert shlex.split(command) == cmd
    assert (tmp_path / "ran").exists()  # it ran, in ROOT
    mirror = tmp_path / "results" / "study" / "lasmp" / "seed0.commands"
    assert mirror.read_text() == log.read_text()  # committed beside the results, once it succeeded
    with pytest.raises(SystemExit) as stop:  # the command's own status, not a CalledProcessError
        study.real_execute([sys.executable, "-c", "raise SystemExit(3)"], log)
    assert stop.value.code == 3
    assert len(log.read_text().splitlines()) == 4 and len(mirror.read_text().splitlines()) == 2


def test_a_failed_training_ends_the_study_with_its_status_and_is_not_added_to_the_committed_commands(
    study, monkeypatch, tmp_path
):
    """The committed .commands file says how the committed results were made: a training that failed
    made none. The uncommitted log beside the run keeps it, with every command tried."""
    monkeypatch.setattr(study.runs, "execute", study.real_execute)
    (tmp_path / "train.py").write_text("raise SystemExit(2)  # as train.py refusing its configuration\n")
    committed = tmp_path / "results" / "study" / "lasmp" / "seed0.commands"
    committed.parent.mkdir(parents=True)
    committed.write_text("# an earlier sitting\ntrain.py seed=0\n")
    with pytest.raises(SystemExit) as stop:
        study.main(["train", "lasmp", "0"])
    assert stop.value.code == 2
    assert committed.read_text() == "# an earlier sitting\ntrain.py seed=0\n"
    tried = (tmp_path / "runs" / "study" / "lasmp" / "seed0.commands").read_text().splitlines()
    assert len(tried) == 2 and "train.py" in tried[1] and "seed=0" in tried[1]


# train.py as it meets a Ctrl-C: the terminal signals its whole foreground process group (this, and the
# study waiting for it); the training saves a checkpoint, which takes a moment, and exits 130
INTERRUPTED_TRAINING = """
import os, signal, time
try:
    os.killpg(0, signal.SIGINT)
    time.sleep(10)
except KeyboardInterrupt:
    time.sleep(0.5)
    open("saved", "w").close()
    print("interrupted: saved model_3.pt", flush=True)
    raise SystemExit(130)
"""


def test_a_ctrl_c_during_training_waits_for_its_save_and_ends_the_study_with_its_status_and_no_traceback(
    tmp_path,
):
    """Python's subprocess.run kills the child a quarter of a second after the parent's interrupt and
    then raises it: the save cut short, a traceback after the training's own last line."""
    (tmp_path / "train.py").write_text(INTERRUPTED_TRAINING)
    study = (
        "import importlib.util, sys\n"
        "from pathlib import Path\n"
        f"sys.path.insert(0, {str(ROOT / 'scripts')!r})  # as `python scripts/study.py` does\n"
        "from studylib import plan, runs\n"
        f"spec = importlib.util.spec_from_file_location('study', {str(ROOT / 'scripts' / 'study.py')!r})\n"
        "study = importlib.util.module_from_spec(spec)\n"
        "spec.loader.exec_module(study)\n"
        f"plan.ROOT = Path({str(tmp_path)!r})\n"
        "plan.RUNS, plan.RESULTS = plan.ROOT / 'runs' / 'study', plan.ROOT / 'results' / 'study'\n"
        "runs.check_learner = lambda: None  # this CPU may lack bfloat16\n"
        "study.main(['train', 'lasmp', '0'])\n"
    )
    done = subprocess.run(  # a session of its own: the Ctrl-C reaches this one and its child, not pytest
        [sys.executable, "-c", study], capture_output=True, text=True, timeout=60, start_new_session=True
    )
    assert done.returncode == 130, done.stderr
    assert (tmp_path / "saved").exists() and done.stdout.endswith("interrupted: saved model_3.pt\n")
    assert "Traceback" not in done.stderr, done.stderr
    assert not (tmp_path / "results" / "study" / "lasmp" / "seed0.commands").exists()


def test_a_recorded_run_keeps_its_policy_in_the_light_form_beside_its_config_and_learning_curve(
    tmp_path, monkeypatch
):
    from testkit import tiny

    from lasmp.algo.checkpoint import read_checkpoint
    from lasmp.algo.checkpoint.light import LIGHT_KIND
    from lasmp.cli.train import train

    mod = Study()  # scripts/study.py's modules, each name set where it is read
    monkeypatch.setattr(mod.plan, "ROOT", tmp_path)
    monkeypatch.setattr(mod.plan, "RUNS", tmp_path / "runs" / "study")
    monkeypatch.setattr(mod.plan, "RESULTS", tmp_path / "results" / "study")
    train(tiny(mod.run_dir("lasmp_plus", 0), plain=True))  # 2 iterations: model_1.pt
    mod.record_run("lasmp_plus", 0, 2)
    out = mod.result_dir("lasmp_plus", 0, 2)
    policy = read_checkpoint(out / "policy_1.pt")
    full = read_checkpoint(mod.run_dir("lasmp_plus", 0) / "model_1.pt")
    assert policy["kind"] == LIGHT_KIND and policy["critic_state_dict"] == {}
    assert all(torch.equal(policy["actor_state_dict"][k], v) for k, v in full["actor_state_dict"].items())
    assert {p.name for p in out.iterdir()} == {"config.yaml", "policy_1.pt", "curves_2.json"}
