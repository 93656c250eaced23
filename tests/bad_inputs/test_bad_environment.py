"""The environment a user brings (lasmp/cli/preflight.py): a MUJOCO_GL that mujoco refuses, runner.logger=wandb
without a W&B login, env.backend=warp without the gpu extra. Each ended in a library's traceback, the
last two only after the envs were built; each is now one line naming the cause (`error: ...`, exit 2),
said before the work starts.

The real entry points run in subprocesses, where a `prelude` can take a package away
(`sys.modules[name] = None`: its import fails as if it were not installed) or make building an env an
error (so that a refusal said after the envs were built fails the test)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from badkit import ROOT, Outcome, _bench_case, call, evaluate, refused, tiny

from lasmp.cli.preflight import wandb_login_error

SHIPPED = ROOT / "resources" / "policies" / "lasmp_a1.pt"
NO_ENV = (
    "import lasmp.envs.registry as r\n"
    "def no_env(*a, **k):\n"
    "    raise AssertionError('an env was built before the environment was checked')\n"
    "r.make_env = no_env\n"
)
NO_MUJOCO_WARP = "import sys\nsys.modules['mujoco_warp'] = None\n"


def cli(
    script: str, *args: str, cwd: Path, prelude: str = "", env: dict | None = None, **more: str
) -> Outcome:
    """`python SCRIPT ARGS` in a subprocess, `prelude` run first in the same interpreter; its environment
    `env` (default: this one's) with the variables `more`."""
    run = f"import runpy, sys\n{prelude}\nsys.argv = {[str(ROOT / script), *args]!r}\n"
    run += f"runpy.run_path({str(ROOT / script)!r}, run_name='__main__')\n"
    done = subprocess.run(
        [sys.executable, "-c", run],
        cwd=cwd,
        env={**(os.environ if env is None else env), "PYTHONUNBUFFERED": "1", **more},
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=300,
    )
    return Outcome(done.returncode, done.stdout + done.stderr)


def one_error_line(out: Outcome, *patterns: str) -> str:
    """A clear refusal whose error is one line holding each pattern."""
    refused(out, *patterns)
    lines = [line for line in out.text.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, out.text[-3000:]
    return lines[0]


# -- MUJOCO_GL -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "script, args",
    [
        ("train.py", tiny("runner.log_dir=run")),
        ("play.py", ["--checkpoint", str(SHIPPED), "--steps", "1"]),
        ("evaluate.py", ["--controller", "stand_still", "--num-trajectories", "1", "--out", "eval"]),
    ],
)
def test_a_mujoco_gl_that_mujoco_refuses_stops_each_entry_point_in_one_line_naming_it(tmp_path, script, args):
    out = cli(script, *args, cwd=tmp_path, MUJOCO_GL="bogus")
    line = one_error_line(out, r"MUJOCO_GL=bogus", "egl", "osmesa")
    assert out.code == 2 and out.text.strip() == line, out.text[-3000:]  # nothing else was said or done
    assert list(tmp_path.iterdir()) == []


# -- runner.logger=wandb ---------------------------------------------------------------------------
def no_wandb_login(home: Path) -> dict:
    """This environment without any W&B setting or credential, HOME an empty directory."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("WANDB_") and k != "NETRC"}
    return {**env, "HOME": str(home)}


def test_a_wandb_logger_without_a_login_is_refused_before_any_env_is_built(tmp_path):
    pytest.importorskip("wandb")
    home = tmp_path / "home"
    home.mkdir()
    run = tmp_path / "run"
    args = tiny("runner.logger=wandb", f"runner.log_dir={run}")
    out = cli("train.py", *args, cwd=tmp_path, prelude=NO_ENV, env=no_wandb_login(home))
    one_error_line(
        out, r"runner\.logger=wandb needs a W&B login", "wandb login", "WANDB_API_KEY", "WANDB_MODE=offline"
    )
    assert out.code == 2 and not run.exists()


def test_a_wandb_login_in_the_netrc_or_the_offline_mode_passes_the_check(tmp_path):
    pytest.importorskip("wandb")
    home = tmp_path / "home"
    home.mkdir()
    # what `wandb login` leaves: the key in ~/.netrc (W&B reads it for its old host too)
    (home / ".netrc").write_text(f"machine api.wandb.ai\n  login user\n  password {'k' * 40}\n")
    (home / ".netrc").chmod(0o600)
    check = "from lasmp.cli.preflight import wandb_login_error\nprint('check:', wandb_login_error())"
    for env in (no_wandb_login(home), {**no_wandb_login(tmp_path), "WANDB_MODE": "offline"}):
        done = subprocess.run(
            [sys.executable, "-c", check], env=env, capture_output=True, text=True, timeout=120
        )
        assert "check: None" in done.stdout, done.stdout + done.stderr
    (home / ".netrc").unlink()  # the control: without it, the same check refuses
    done = subprocess.run(
        [sys.executable, "-c", check], env=no_wandb_login(home), capture_output=True, text=True
    )
    assert "needs a W&B login" in done.stdout, done.stdout + done.stderr


def test_a_wandb_api_key_in_the_environment_passes_the_check_without_asking_wandb(monkeypatch):
    monkeypatch.setenv("WANDB_API_KEY", "k" * 40)
    monkeypatch.setitem(sys.modules, "wandb", None)  # never imported: the key is enough
    assert wandb_login_error() is None


# -- env.backend=warp --------------------------------------------------------------------------------
def test_the_warp_backend_without_mujoco_warp_is_refused_before_any_env_is_built(tmp_path):
    run = tmp_path / "run"
    args = tiny("env.backend=warp", f"runner.log_dir={run}")
    out = cli("train.py", *args, cwd=tmp_path, prelude=NO_ENV + NO_MUJOCO_WARP)
    one_error_line(out, r"env\.backend=warp needs MuJoCo Warp", r'pip install -e "\.\[gpu\]"')
    assert out.code == 2 and not run.exists()


@pytest.fixture
def warp_checkpoint(tmp_path) -> Path:
    """The shipped policy as if it had been trained on env.backend=warp."""
    data = torch.load(SHIPPED, weights_only=True)
    data["config"]["env"]["backend"] = "warp"
    path = tmp_path / "warp_policy.pt"
    torch.save(data, path)
    return path


def test_play_and_evaluate_of_a_warp_checkpoint_without_mujoco_warp_are_refused_naming_it(
    tmp_path, warp_checkpoint, monkeypatch
):
    from lasmp.cli.play import main as play

    def no_env(*args, **kwargs):
        raise AssertionError("an env was built before the backend was checked")

    monkeypatch.setitem(sys.modules, "mujoco_warp", None)
    monkeypatch.setattr("lasmp.deploy.make_env", no_env)
    monkeypatch.setattr("lasmp.eval.build.policy_eval_env", no_env)
    wanted = (rf"checkpoint .*{warp_checkpoint.name} was trained with env\.backend=warp", r"\[gpu\]")
    out = call(play, ["--checkpoint", str(warp_checkpoint), "--steps", "1"])
    one_error_line(out, *wanted)
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    argv = ["--checkpoint", str(warp_checkpoint), "--benchmark", str(bench), "--num-trajectories", "1"]
    out = evaluate(*argv, "--out", str(tmp_path / "eval"))
    one_error_line(out, *wanted)
    assert not (tmp_path / "eval").exists()
