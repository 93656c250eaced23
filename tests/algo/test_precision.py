"""The learner's precision (`algo.precision`): hardware detection, what `auto` / `float32` /
`bfloat16` build, the refusal of an unknown value, and a tiny training with the default."""

from __future__ import annotations

import pytest
import torch
from testkit import tiny

from lasmp.algo import precision as prec
from lasmp.algo.precision import cpu_has_fast_bf16, resolve_precision
from lasmp.cli.build import make_runner
from lasmp.cli.train import train
from lasmp.config.checks import ConfigError

AVX2_ONLY = """processor\t: 0
vendor_id\t: AuthenticAMD
model name\t: AMD EPYC
flags\t\t: fpu vme sse sse2 ssse3 fma sse4_1 sse4_2 avx avx2 bmi1 bmi2
bogomips\t: 4899.99
"""


def test_bf16_detection_reads_the_cpu_flags():
    assert not cpu_has_fast_bf16(AVX2_ONLY)
    assert not cpu_has_fast_bf16(AVX2_ONLY.replace("avx2", "avx2 avx512f avx512bw avx512_vnni"))
    assert cpu_has_fast_bf16(AVX2_ONLY.replace("avx2", "avx2 avx512f avx512_bf16"))
    assert cpu_has_fast_bf16(AVX2_ONLY.replace("avx2", "avx2 amx_bf16 amx_tile"))
    # a flag's name elsewhere in the text is not a flag
    assert not cpu_has_fast_bf16(AVX2_ONLY.replace("AMD EPYC", "avx512_bf16 lookalike"))


@pytest.fixture
def no_bf16_cpu(monkeypatch):
    """This CPU without native bfloat16, whatever the machine running the tests has."""
    monkeypatch.setattr(prec, "cpu_has_fast_bf16", lambda cpuinfo=None: False)


def test_auto_on_a_cpu_without_bf16_builds_a_float32_learner_with_fused_adam(tmp_path, no_bf16_cpu):
    cfg = tiny(tmp_path)
    assert cfg.algo.precision == "auto"  # the default
    runner = make_runner(cfg, None)
    alg = runner.alg
    assert not alg.use_mixed_precision and not alg.learner_precision.bf16_autocast
    assert alg.optimizer.defaults["fused"] and alg.estimator_optimizer.defaults["fused"]
    assert "lacks AVX-512 BF16/AMX" in alg.learner_precision.line()
    alg.learner_precision.compile_mlps = False  # the autocast is what is checked here: spare the compile
    seen = []
    real = alg.actor.roa_losses
    alg.actor.roa_losses = lambda obs, lam: seen.append(torch.is_autocast_enabled("cpu")) or real(obs, lam)
    rollout(runner)
    alg.update()
    assert seen and not any(seen)


def rollout(runner):
    obs = runner.env.get_observations()
    with torch.inference_mode():
        for _ in range(runner.cfg["num_steps_per_env"]):
            obs, rew, dones, extras = runner.env.step(runner.alg.act(obs))
            runner.alg.process_env_step(obs, rew, dones, extras)
        runner.alg.compute_returns(obs)


def test_auto_on_a_cpu_with_bf16_turns_the_autocast_on(monkeypatch):
    monkeypatch.setattr(prec, "cpu_has_fast_bf16", lambda cpuinfo=None: True)
    monkeypatch.setattr(prec, "bf16_matmul_speedup", lambda: 2.4)  # the AMD EPYC of docs/performance.md
    plan = resolve_precision("auto", "cpu")
    assert plan.bf16_autocast and plan.fused_adam and plan.compile_mlps
    assert plan.line().startswith("learner: bfloat16 autocast, fused Adam")


def test_auto_keeps_float32_where_the_flag_is_there_but_bf16_products_measure_slower(monkeypatch):
    monkeypatch.setattr(prec, "cpu_has_fast_bf16", lambda cpuinfo=None: True)
    monkeypatch.setattr(prec, "bf16_matmul_speedup", lambda: 0.54)  # the Intel Xeon without AMX
    plan = resolve_precision("auto", "cpu")
    assert not plan.bf16_autocast and plan.fused_adam and plan.compile_mlps
    assert "measured 0.54x float32's speed" in plan.line()
    with pytest.warns(UserWarning, match="measured 0.54x"):  # forced, it runs, saying so
        assert resolve_precision("bfloat16", "cpu").bf16_autocast


def test_the_bf16_probe_is_not_run_where_the_flags_say_bf16_is_emulated(monkeypatch, no_bf16_cpu):
    def never():
        raise AssertionError("emulated bfloat16 products are slow: no probe without the flag")

    monkeypatch.setattr(prec, "bf16_matmul_speedup", never)
    assert not resolve_precision("auto", "cpu").bf16_autocast


@pytest.mark.skipif(not cpu_has_fast_bf16(), reason="the probe runs only where the flags promise bf16")
def test_the_bf16_probe_measures_a_speed_ratio_on_this_cpu():
    prec.bf16_matmul_speedup.cache_clear()
    speedup = prec.bf16_matmul_speedup(rounds=1, reps=1)
    assert 0.01 < speedup < 100  # a ratio of two timings of one product, not a constant
    assert resolve_precision("auto", "cpu").bf16_autocast == (
        prec.bf16_matmul_speedup() >= prec.BF16_MIN_SPEEDUP
    )


def test_float32_is_the_plain_learner(tmp_path, capsys):
    runner = make_runner(tiny(tmp_path, algo={"precision": "float32"}), None)
    alg = runner.alg
    assert not alg.use_mixed_precision
    assert not alg.optimizer.defaults.get("fused") and not alg.estimator_optimizer.defaults.get("fused")
    alg.start_learner()
    assert not alg._compiled
    nets = [alg.actor.mlp, alg.critic.mlp, alg.actor.encoder.mlp, *alg.actor.estimators()]
    assert all(getattr(net, "_compiled_call_impl", None) is None for net in nets)
    line = "learner: float32, Adam, eager MLPs (algo.precision=float32)"
    assert capsys.readouterr().out.strip().endswith(line)


def test_forced_bf16_on_a_cpu_without_it_warns_and_runs_the_autocast(no_bf16_cpu):
    with pytest.warns(UserWarning, match="algo.precision=bfloat16 but this CPU lacks"):
        plan = resolve_precision("bfloat16", "cpu")
    assert plan.bf16_autocast and "forced" in plan.line()


def test_a_per_part_switch_overrides_the_precision(no_bf16_cpu):
    plan = resolve_precision("auto", "cpu", fused_adam=False, compile_mlps=False)
    assert not plan.bf16_autocast and not plan.fused_adam and not plan.compile_mlps
    assert "Adam (algo.fused_adam=false)" in plan.line()
    assert resolve_precision("float32", "cpu", use_mixed_precision=True).bf16_autocast


def test_a_compiler_that_fails_falls_back_to_eager_saying_why(monkeypatch, no_bf16_cpu):
    failed = (False, "torch.compile failed: no C++ compiler")
    monkeypatch.setattr(prec, "compile_works", lambda device: failed)
    plan = resolve_precision("auto", "cpu")
    plan.check_compiler("cpu")
    assert not plan.compile_mlps
    assert plan.line().endswith("eager MLPs (torch.compile failed: no C++ compiler) (algo.precision=auto)")


def test_an_unknown_precision_is_refused_naming_the_field(tmp_path):
    message = r"algo\.precision must be one of auto \| float32 \| bfloat16, got 'fp16'"
    with pytest.raises(ConfigError, match=message):
        tiny(tmp_path, algo={"precision": "fp16"})


def test_a_tiny_training_with_auto_runs_and_records_the_learner(tmp_path, capsys, no_bf16_cpu):
    runner = train(tiny(tmp_path))
    assert runner.current_learning_iteration == 1  # iterations 0 and 1
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.startswith("learner: ")]
    assert len(lines) == 1 and lines[0].endswith("(algo.precision=auto)")
    assert lines[0].startswith("learner: float32 (this CPU lacks") and "fused Adam" in lines[0]
    assert len([line for line in out.splitlines() if line.startswith("it ")]) == 2
    data = torch.load(tmp_path / "model_1.pt", weights_only=True)
    assert data["config"]["algo"]["precision"] == "auto"
    assert data["learner_precision"]["line"] == lines[0] and not data["learner_precision"]["bf16_autocast"]


def test_the_cpuinfo_reading_agrees_with_torch_s_own_probe():
    caps = getattr(torch.cpu, "get_capabilities", None)
    try:
        with open("/proc/cpuinfo") as f:
            text = f.read()
    except OSError:
        pytest.skip("no /proc/cpuinfo")
    if caps is None:
        pytest.skip("torch has no CPU feature probe")
    assert cpu_has_fast_bf16(text) == any(caps().get(flag, False) for flag in prec.BF16_CPU_FLAGS)


def test_a_resume_keeps_this_learner_s_adam_kernel(tmp_path, no_bf16_cpu):
    fp32 = {"precision": "float32"}
    train(tiny(tmp_path / "a", algo=fp32, runner={"max_iterations": 1}))
    fused = make_runner(tiny(tmp_path / "b", algo={"compile_mlps": False}), None)
    fused.load(str(tmp_path / "a"))  # a float32 run's (unfused) optimizer states
    plain = make_runner(tiny(tmp_path / "c", algo=fp32), None)
    plain.load(str(tmp_path / "a"))
    for runner, kernel in ((fused, True), (plain, None)):
        for opt in (runner.alg.optimizer, runner.alg.estimator_optimizer):
            assert all(g["fused"] is kernel for g in opt.param_groups)
            assert all(s["step"].dtype == torch.float32 for s in opt.state.values())
    again = make_runner(tiny(tmp_path / "d", algo=fp32), None)
    fused.save(str(tmp_path / "b" / "model_9.pt"))
    again.load(str(tmp_path / "b" / "model_9.pt"))  # and back: a fused run's states into the plain Adam
    assert all(g["fused"] is None for g in again.alg.optimizer.param_groups)
