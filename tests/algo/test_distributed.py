"""Data-parallel training with torchrun on a CPU: 2 gloo processes at tiny sizes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf
from testkit import tiny

from lasmp.algo.checkpoint import read_checkpoint

ROOT = Path(__file__).resolve().parents[2]
WORKER = ROOT / "tests" / "algo" / "dist_worker.py"


def torchrun(*args, timeout=300, **kwargs) -> subprocess.CompletedProcess:
    cmd = [
        sys.executable,
        "-m",
        "torch.distributed.run",
        "--standalone",
        "--nproc_per_node=2",
        *map(str, args),
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT, **kwargs)


def run_worker(tmp_path: Path, cfg: dict, out: Path) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    done = torchrun(WORKER, json.dumps(cfg), out)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    return [torch.load(out / f"rank{k}.pt", weights_only=True) for k in (0, 1)], done.stdout


def assert_same_parameters(ranks: list[dict]) -> None:
    for net in ("actor", "critic"):
        a, b = ranks[0][net], ranks[1][net]
        assert a.keys() == b.keys()
        for name in a:
            assert torch.equal(a[name], b[name]), f"{net}.{name} differs between the ranks"
    # the estimators' own optimizer (the ROA pass) stepped the same averaged gradients on both
    for index, state in ranks[0]["estimators"].items():
        for key, value in state.items():
            assert torch.equal(value, ranks[1]["estimators"][index][key]), f"estimator Adam {index}.{key}"


@pytest.fixture(scope="module")
def two_ranks(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("dp")
    tiny_run = tiny(tmp / "run", steps=5, precision="float32", plain=True, runner={"max_iterations": 3})
    cfg = OmegaConf.to_container(tiny_run)
    ranks, stdout = run_worker(tmp, cfg, tmp / "out")
    return tmp, cfg, ranks, stdout


def test_two_processes_end_with_identical_parameters_and_normalizers(two_ranks):
    _, _, ranks, _ = two_ranks
    assert_same_parameters(ranks)
    # the normalizers learned from both ranks' observations, and agree (counts include both)
    counts = [r["actor"][k] for r in ranks for k in r["actor"] if k.endswith("count")]
    assert counts and all(c > 0 for c in counts)
    assert ranks[0]["iteration"] == ranks[1]["iteration"] == 2


def test_each_rank_steps_its_own_envs_but_shares_one_curriculum(two_ranks):
    _, _, ranks, _ = two_ranks
    assert [r["seed"] for r in ranks] == [0, 1]  # seed + rank
    assert ranks[0]["curriculum"] == ranks[1]["curriculum"]


def test_rank_0_alone_logs_and_saves_every_ranks_running_state(two_ranks):
    tmp, _, _, stdout = two_ranks
    run = tmp / "run"
    assert len(list(run.glob("events.out.tfevents.*"))) == 1
    assert stdout.count("it 2/2") == 1  # one progress line per iteration, from rank 0
    assert "x 2 processes" in stdout
    data = read_checkpoint(run / "model_2.pt")
    assert data["world_size"] == 2 and len(data["other_ranks"]) == 1
    assert data["other_ranks"][0]["run"]["num_envs"] == 4


def test_a_two_process_run_resumes_in_its_directory_with_identical_parameters(two_ranks):
    tmp, cfg, _, _ = two_ranks
    resumed = {**cfg, "resume": str(tmp / "run"), "runner": {**cfg["runner"], "max_iterations": 2}}
    ranks, stdout = run_worker(tmp, resumed, tmp / "out_resumed")
    assert "resumed from" in stdout and ranks[0]["iteration"] == ranks[1]["iteration"] == 4
    assert_same_parameters(ranks)
    assert (tmp / "run" / "model_4.pt").exists()


def test_one_process_refuses_a_two_process_checkpoint_unless_told_to_restart_the_episodes(
    two_ranks, tmp_path
):
    tmp, _, _, _ = two_ranks
    args = [
        f"resume={tmp / 'run'}",  # its newest full checkpoint: model_2.pt, or model_4.pt once resumed
        f"runner.log_dir={tmp_path / 'branch'}",
        "runner.max_iterations=1",
        "algo.precision=float32",
        "torch_threads=1",
    ]
    out = subprocess.run(
        [sys.executable, "train.py", *args], capture_output=True, text=True, cwd=ROOT, timeout=300
    )
    assert (
        out.returncode == 2
        and "2 process(es), this job has 1" in out.stderr
        and "Traceback" not in out.stderr
    )
    again = subprocess.run(
        [sys.executable, "train.py", *args, "resume_drop_env_state=true"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )
    assert again.returncode == 0, again.stderr[-2000:]


def _long_two_process_run(run: Path, save_interval: int) -> subprocess.Popen:
    """A tiny two-process torchrun of 500 iterations into `run`, its output piped (stopped by the test)."""
    args = [
        "train.py",
        "env.num_envs=4",
        "runner.max_iterations=500",
        f"runner.save_interval={save_interval}",
        "runner.num_steps_per_env=5",
        "policy.actor_hidden_dims=[32,32,32]",
        "policy.critic_hidden_dims=[32,32]",
        "algo.precision=float32",
        "torch_threads=1",
        f"runner.log_dir={run}",
    ]
    cmd = [
        sys.executable,
        "-m",
        "torch.distributed.run",
        "--standalone",
        "--nproc_per_node=2",
        *args,
    ]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT)


def _wait_for_iteration(proc: subprocess.Popen, it: int, timeout_s: float = 240) -> None:
    """Read `proc`'s output until its progress line of iteration `it`."""
    deadline = time.monotonic() + timeout_s
    for line in proc.stdout:
        if line.startswith(f"it {it}/"):
            return
        assert time.monotonic() < deadline, f"no iteration {it} in time"
    raise AssertionError(f"the run ended before iteration {it}")


def test_sigterm_to_the_job_stops_both_ranks_after_the_same_iteration_with_one_checkpoint(tmp_path):
    run = tmp_path / "run"
    proc = _long_two_process_run(run, save_interval=1000)
    try:
        _wait_for_iteration(proc, 2)
        proc.send_signal(signal.SIGTERM)
        rest, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    saved = sorted(p.name for p in run.glob("model_*.pt"))
    # the first iteration's and the stop's; the job's last output says why otherwise
    assert len(saved) == 2 and saved[0] == "model_0.pt", (saved, rest[-3000:])
    stopped = int(saved[1].removeprefix("model_").removesuffix(".pt"))
    assert rest.count(f"stopped after iteration {stopped}") == 1 and "resume with" in rest
    data = read_checkpoint(run / saved[1])
    assert data["iter"] == stopped and len(data["other_ranks"]) == 1


def test_a_signal_that_lands_during_the_stop_collective_is_counted_at_the_next_iteration_end(monkeypatch):
    """The race that could lose a SIGTERM: the handler runs while the rank waits in the all-reduce it
    gave 0 to; were the reduced 0 to overwrite the handler's record, no rank would ever stop, and
    torchrun would kill the job 30 s later without a checkpoint."""
    from lasmp.algo import distributed as dp
    from lasmp.algo.runner import LasmpRunner

    runner = LasmpRunner.__new__(LasmpRunner)  # the decision reads nothing but the signal state
    runner._signal, runner.device = None, "cpu"
    given = []

    def all_reduce_max_of_one_rank(flag, device):
        given.append(flag)
        if len(given) == 1:
            runner._on_signal(signal.SIGTERM, None)  # arrives while this rank waits for the others
        return flag

    monkeypatch.setattr(dp, "any_rank", all_reduce_max_of_one_rank)
    assert runner._agreed_signal() is None  # this iteration's answer was already given
    assert runner._agreed_signal() == signal.SIGTERM and given == [0, signal.SIGTERM]


def _curriculum_rank(rank: int, port: int, out: str) -> None:
    import torch.distributed as dist

    from lasmp.envs.curriculum import SharedCurriculum

    dist.init_process_group("gloo", init_method=f"tcp://127.0.0.1:{port}", rank=rank, world_size=2)
    c = SharedCurriculum(level_min=5, level_max=6, promote_success_rate=0.8, window_episodes=10)
    # rank 0 succeeds in all of its 6 episodes, rank 1 in 2 of 4: 8 of 10 over both ranks promotes,
    # though neither rank alone has a full window
    ok = [True] * 6 if rank == 0 else [True, True, False, False]
    assert c.update(np.full(len(ok), 5), np.array(ok)) is False and c.level == 5  # collected, not fed
    rose = c.sync()
    torch.save({"rose": rose, "state": c.state_dict()}, f"{out}/curriculum{rank}.pt")
    dist.destroy_process_group()


def test_the_shared_curriculum_promotes_on_the_success_rate_over_all_ranks_episodes(tmp_path):
    import socket

    import torch.multiprocessing as mp

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    mp.spawn(_curriculum_rank, args=(port, str(tmp_path)), nprocs=2, join=True)
    states = [torch.load(tmp_path / f"curriculum{k}.pt", weights_only=True) for k in (0, 1)]
    assert states[0] == states[1]
    assert states[0]["rose"] and states[0]["state"] == {"level": 6, "window": []}


def _rank_pids(agent: int) -> dict[int, int]:
    """The torchrun workers started by the agent process `agent`: {RANK: pid}."""
    found = {}
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            ppid = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])
            env = dict(e.split(b"=", 1) for e in (proc / "environ").read_bytes().split(b"\0") if b"=" in e)
        except (OSError, ValueError, IndexError):
            continue
        if ppid == agent and b"RANK" in env:
            found[int(env[b"RANK"])] = int(proc.name)
    return found


@pytest.mark.parametrize("victim", [1, 0])
def test_a_killed_rank_leaves_the_other_saying_what_happened_and_how_to_resume(tmp_path, victim):
    """D04 / D05: SIGKILL to one rank mid-run. The other's next collective fails (gloo: `Connection
    closed by peer`), and torchrun's agent sends it SIGTERM a fraction of a second after the kill; it
    must end with one message naming the newest checkpoint and the resume command, not with the
    collective's traceback nor cut by the SIGTERM."""
    run = tmp_path / "run"
    proc = _long_two_process_run(run, save_interval=2)  # torchrun's default monitor interval
    try:
        _wait_for_iteration(proc, 3)
        pids = _rank_pids(proc.pid)
        assert set(pids) == {0, 1}, pids
        os.kill(pids[victim], signal.SIGKILL)
        rest, _ = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
    survivor = 1 - victim
    assert proc.returncode != 0
    said = [line for line in rest.splitlines() if line.startswith("error: ")]
    assert len(said) == 1 and f"rank {survivor} of the torchrun job lost the connection" in said[0], rest[
        -4000:
    ]
    newest = max(run.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))
    assert f"The newest checkpoint is {newest}" in said[0], rest[-4000:]
    assert "torchrun --nproc_per_node=2 train.py" in rest and f"resume={newest}" in rest
    # torchrun's own ChildFailedError summary remains; no traceback of the worker's
    assert "Connection closed by peer" not in rest and "lasmp/cli/train.py" not in rest, rest[-4000:]
    # the agent terminates the survivor as soon as it sees the victim gone: the survivor still ends
    # with its own exit code 1, its report whole, not by that SIGTERM
    assert "Signal 15 (SIGTERM) received" not in rest and "exitcode  : 1 " in rest, rest[-4000:]
