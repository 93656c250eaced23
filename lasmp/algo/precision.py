"""How the learner computes (`algo.precision`): bfloat16 autocast, the fused Adam and compiled MLPs,
each where the hardware and the installation have it, and one line that says what runs and why.

`auto` takes each part that pays here: bfloat16 autocast only on a CPU with AVX-512 BF16 or AMX (on
others oneDNN emulates bfloat16 and the matrix products run several times slower) where a matrix
product of the learner's size also measures faster in bfloat16 than in float32 (the flag alone
cannot tell: docs/performance.md#the-learners-precision-algoprecision), or on a GPU with native
bfloat16; the fused Adam where torch has it for the device; compiled MLPs where a tiny
`torch.compile` succeeds (on a CPU it needs a C++ compiler). `float32` takes none of them: no
autocast, rsl_rl's Adam, eager networks, the same learner wherever it runs, so that a seeded run
repeats the curve of a float32 run of its seed.
`bfloat16` forces the autocast (with a warning where it is emulated). The per-part switches
`algo.use_mixed_precision`, `algo.fused_adam`, `algo.compile_mlps` (null: as `precision` says)
override one part; all three false is the float32 learner, whatever `precision` says.
"""

from __future__ import annotations

import functools
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import torch

PRECISIONS = ("auto", "float32", "bfloat16")  # the values of algo.precision
BF16_CPU_FLAGS = ("avx512_bf16", "amx_bf16")  # x86 /proc/cpuinfo flags of native bfloat16 matrix products
# (ours) bfloat16 autocast pays on a CPU only where its matrix products measure at least this much
# faster than float32's: the update also pays for the casts
# (docs/performance.md#the-learners-precision-algoprecision)
BF16_MIN_SPEEDUP = 1.25
# the probe's product: a minibatch of the default config (1,024 envs x 12 steps / 4) through a hidden layer
PROBE_SHAPE = (3072, 512, 256)


def cpu_has_fast_bf16(cpuinfo: str | None = None) -> bool:
    """Whether this CPU multiplies bfloat16 matrices natively (AVX-512 BF16 or AMX).

    `cpuinfo`: the text of /proc/cpuinfo (read when None, on Linux); where there is none, torch's own
    CPU feature probe (`torch.cpu.get_capabilities`) answers."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            caps = getattr(torch.cpu, "get_capabilities", dict)()
            return any(bool(caps.get(flag)) for flag in BF16_CPU_FLAGS)
    flags = set()
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "flags":
            flags.update(value.split())
    return any(flag in flags for flag in BF16_CPU_FLAGS)


@functools.cache
def bf16_matmul_speedup(rounds: int = 3, reps: int = 4) -> float:
    """How many times faster this CPU multiplies a learner-sized matrix product (`PROBE_SHAPE`) in
    bfloat16 than in float32, on torch's threads: the best of `rounds` interleaved timings of `reps`
    products each, so that a load on the machine slows both sides alike; once per process. Run
    only where the flags promise native bfloat16 (where it is emulated it is slow)."""
    rows, inner, cols = PROBE_SHAPE
    gen = torch.Generator().manual_seed(0)
    a, b = torch.randn(rows, inner, generator=gen), torch.randn(inner, cols, generator=gen)
    pairs = {dtype: (a.to(dtype), b.to(dtype)) for dtype in (torch.float32, torch.bfloat16)}
    best = dict.fromkeys(pairs, float("inf"))
    with torch.inference_mode():
        for x, y in pairs.values():  # warm-up: oneDNN picks and builds its kernel
            torch.mm(x, y)
        for _ in range(rounds):
            for dtype, (x, y) in pairs.items():
                start = time.perf_counter()
                for _ in range(reps):
                    torch.mm(x, y)
                best[dtype] = min(best[dtype], time.perf_counter() - start)
    return best[torch.float32] / best[torch.bfloat16]


def _bf16(device: torch.device) -> tuple[bool, str]:
    """(bfloat16 pays on this device, why not)."""
    if device.type == "cuda":
        if torch.cuda.is_bf16_supported(including_emulation=False):
            return True, ""
        return False, "this GPU lacks native bfloat16"
    if device.type != "cpu" or not cpu_has_fast_bf16():
        return False, "this CPU lacks AVX-512 BF16/AMX: bfloat16 would be emulated, several times slower"
    speedup = bf16_matmul_speedup()
    if speedup < BF16_MIN_SPEEDUP:
        return False, (
            f"this CPU's bfloat16 matrix products measured {speedup:.2f}x float32's speed, "
            f"under the {BF16_MIN_SPEEDUP}x that pays"
        )
    return True, ""


@functools.cache
def fused_adam_works(device: str) -> tuple[bool, str]:
    """(torch's fused Adam runs on this device, why not): one step on a one-element parameter."""
    try:
        p = torch.zeros(1, device=device, requires_grad=True)
        p.grad = torch.ones_like(p)
        torch.optim.Adam([p], fused=True).step()
        return True, ""
    except (RuntimeError, NotImplementedError) as err:  # what torch raises where no fused kernel exists
        return False, f"no fused Adam on {device}: {_first_line(err)}"


@functools.cache
def compile_works(device: str) -> tuple[bool, str]:
    """(torch.compile builds and runs a tiny kernel on this device, why not). It imports the compiler
    stack, which the real compilation needs anyway."""
    try:
        with torch.inference_mode(False), torch.no_grad():
            x = torch.linspace(-2.0, 2.0, 16, device=device)
            out = torch.compile(lambda t: torch.nn.functional.elu(t) * 2.0 + 1.0)(x)
            if not torch.allclose(out, torch.nn.functional.elu(x) * 2.0 + 1.0):
                return False, "torch.compile gave wrong values on a test kernel"
        return True, ""
    except Exception as err:  # no C++ compiler, no triton, an unsupported platform, ...
        return False, f"torch.compile failed: {_first_line(err)}"


def _first_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return (text[0] if text else type(err).__name__)[:160]


@dataclass
class LearnerPrecision:
    """What the learner runs: each part on or off, and why (for the start-up line)."""

    precision: str
    bf16_autocast: bool
    fused_adam: bool
    compile_mlps: bool  # wanted; `check_compiler` turns it off where torch.compile does not work
    why: dict[str, str]  # part -> reason it is off (or forced)

    def check_compiler(self, device: str) -> None:
        if self.compile_mlps and self.why.get("compile") is None:
            ok, why = compile_works(device)
            if not ok:
                self.compile_mlps, self.why["compile"] = False, why

    def record(self) -> dict:
        """Plain values for a checkpoint: the parts that ran and the start-up line."""
        return {
            "precision": self.precision,
            "bf16_autocast": self.bf16_autocast,
            "fused_adam": self.fused_adam,
            "compile_mlps": self.compile_mlps,
            "line": self.line(),
        }

    def line(self) -> str:
        """`learner: float32 (why), fused Adam, compiled MLPs (algo.precision=auto)`."""
        parts = [
            ("bfloat16 autocast" if self.bf16_autocast else "float32", "bf16"),
            ("fused Adam" if self.fused_adam else "Adam", "fused"),
            ("compiled MLPs" if self.compile_mlps else "eager MLPs", "compile"),
        ]
        said = [f"{text} ({self.why[key]})" if self.why.get(key) else text for text, key in parts]
        return f"learner: {', '.join(said)} (algo.precision={self.precision})"


def resolve_precision(
    precision: str,
    device: str,
    use_mixed_precision: bool | None = None,
    fused_adam: bool | None = None,
    compile_mlps: bool | None = None,
) -> LearnerPrecision:
    """The learner's parts for `algo.precision` on `device`; a per-part switch that is not None wins.
    Cheap: the compiler is checked later (`LearnerPrecision.check_compiler`), when training starts."""
    if precision not in PRECISIONS:
        raise ValueError(f"algo.precision must be one of {' | '.join(PRECISIONS)}, got {precision!r}")
    dev = torch.device(device)
    why: dict[str, str] = {}
    if use_mixed_precision is not None:
        bf16 = use_mixed_precision
        why["bf16"] = f"algo.use_mixed_precision={str(bf16).lower()}"
    elif precision == "float32":
        bf16, why["bf16"] = False, ""
    else:
        bf16, missing = _bf16(dev)
        if precision == "bfloat16":
            if not bf16:
                warnings.warn(f"algo.precision=bfloat16 but {missing}", stacklevel=2)
                why["bf16"] = f"forced, though {missing}"
            bf16 = True
        elif not bf16:
            why["bf16"] = missing
    if fused_adam is not None:
        fused, why["fused"] = fused_adam, f"algo.fused_adam={str(fused_adam).lower()}"
    elif precision == "float32":
        fused = False
    else:
        fused, why["fused"] = fused_adam_works(str(dev))
    if compile_mlps is not None:
        compiled, why["compile"] = compile_mlps, f"algo.compile_mlps={str(compile_mlps).lower()}"
    else:
        compiled = precision != "float32"
    return LearnerPrecision(precision, bf16, fused, compiled, {k: v for k, v in why.items() if v})
