"""`python evaluate.py`: measure a controller on the benchmark (docs/method.md, Evaluation).

    python evaluate.py --checkpoint PATH [--plot-estimates]      # a trained LAS-MP policy (deployment mode)
    python evaluate.py --controller stand_still                   # PD to q_nominal, a = 0
    python evaluate.py --controller rs --checkpoint RS_PATH       # the R-S policy, zero velocity command
    python evaluate.py --controller rs_oracle --checkpoint RS_PATH  # R-S with the oracle command (below)
    python evaluate.py --suite real_motion --controller stand_still   # ship, bus, train, lift, aircraft
    options: --benchmark xi_eval|validation|FILE (default xi_eval: benchmarks/xi_eval.npz, made on first
               use; validation: benchmarks/validation.npz, the set every choice is made on)
             --trajectories FILE (any trajectory file; robots still come from the benchmark)
             --num-trajectories K (the first K episodes) --out DIR --force --batch-envs 1024 --seed 0
             --torch-threads 1 (the policy's CPU threads) --no-platform-probe
    suite options: --robots-per-scenario R (default 64) --platform-drive close|paper --scenarios NAME ...

Writes DIR/metrics.json (strict JSON: a missing value is null; it records the seed and the SHA-256
of the benchmark and checkpoint files), DIR/metrics.md and DIR/episodes.csv.gz (gzip-compressed CSV,
one row per episode: lasmp/eval/episodes.py; `python -m lasmp.eval.breakdown DIR` reads it; the
suite's has one row per scenario and robot, with its initial heading: lasmp/eval/real_motion/suite.py),
prints metrics.md and, last, one line naming DIR and the files written there. Definitions:
lasmp/eval/metrics.py and docs/evaluation.md.

The default DIR is eval/<controller> for Stand Still, else eval/<run directory>-<hash>/<checkpoint
stem> (plus _rs or _rs_oracle; the hash is of the run directory's full path), so no two checkpoint
files share one. DIR is claimed before any episode is played and the result put in place whole, as
one unit (lasmp/eval/outdir.py): a DIR with a metrics.json is refused unless --force, one that another
evaluation writes is refused, and an unwritable one fails at once. On a disk that fills meanwhile,
the metrics are printed all the same, with one line naming the file (exit 1); Ctrl-C says in one
line what was written (exit 130).
The platform probe (for episodes.csv.gz's feasibility columns) replays every episode's platform
motion in full, a second pass about as long as a Stand Still evaluation; --no-platform-probe
leaves those columns empty.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import torch

from lasmp.algo.checkpoint import CheckpointError
from lasmp.envs import trajectories as trj
from lasmp.eval import benchmark as bm
from lasmp.eval import episodes as ep
from lasmp.eval import outdir as od
from lasmp.eval import platform_probe as pp
from lasmp.eval.build import (
    DEFAULT_BENCHMARK,
    benchmark_arg,
    build,
    eval_env_overrides,
    load_or_make_benchmark,
)
from lasmp.eval.gait import summarize_gait
from lasmp.eval.metrics import ALL_METRICS, metric_h_des_p_m, summarize
from lasmp.eval.mirror import MirroredBenchmark, mirror_report
from lasmp.eval.paper import paper_key, paper_row
from lasmp.eval.report import markdown, plot_estimates
from lasmp.eval.run import run_benchmark
from lasmp.io import errors
from lasmp.io.inputs import int_arg, seed_arg

NUM_BATCHES = 10


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument(
        "--checkpoint", help="a checkpoint file or run directory (LAS-MP, or R-S for rs/rs_oracle)"
    )
    p.add_argument(
        "--controller",
        choices=["stand_still", "rs", "rs_oracle"],
        help="a baseline (default with --checkpoint: the checkpoint's own LAS-MP policy)",
    )
    p.add_argument(
        "--benchmark",
        type=benchmark_arg,
        default=DEFAULT_BENCHMARK,
        help="xi_eval (the test set, default), validation (the set choices are made on) or a .npz file",
    )
    p.add_argument("--trajectories", type=Path, help="a trajectory file to play instead of the benchmark's")
    p.add_argument(
        "--num-trajectories", type=int_arg(1), default=None, help="the first K episodes (default: all)"
    )
    p.add_argument("--batch-envs", type=int_arg(1), default=1024)
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="default: eval/stand_still, or eval/<run directory>-<hash>/<checkpoint stem>[_rs|_rs_oracle]",
    )
    p.add_argument("--force", action="store_true", help="overwrite a result already in --out")
    p.add_argument(
        "--no-platform-probe",
        action="store_true",
        help="skip the platform probe: episodes.csv.gz's feasibility columns stay empty",
    )
    p.add_argument(
        "--plot-estimates", action="store_true", help="estimated vs true x_exp over episode 0 (PNG)"
    )
    p.add_argument(
        "--seed", type=seed_arg, default=0, help="the envs' and the policy's seed, in [0, 2**32-1]"
    )
    p.add_argument(
        "--mirror",
        type=int_arg(1),
        default=None,
        metavar="K",
        help="also play the mirror twins of the first K episodes and compare the failures (lasmp/eval/mirror.py)",
    )
    p.add_argument("--suite", choices=["real_motion"], help="play a scenario suite instead of the benchmark")
    p.add_argument("--scenarios", nargs="+", help="with --suite: only these scenarios (default: all)")
    p.add_argument(
        "--robots-per-scenario",
        type=int_arg(1),
        default=None,
        help="with --suite: the benchmark's first R robots play every scenario (default 64)",
    )
    p.add_argument(
        "--platform-drive",
        choices=["close", "paper"],
        default=None,
        help="with --suite: the platform follows the scenario closely (default) or through the "
        "paper's soft drive",
    )
    p.add_argument(
        "--torch-threads",
        type=int_arg(1),
        default=1,
        help="torch's CPU threads for the policy (default 1: its per-step networks are small, and more "
        "threads contend with the physics thread pool, on a shared machine badly)",
    )
    return p


def main(argv=None, motions=None) -> int:
    """`motions` (with --suite, from code): Motion objects to play instead of the suite's named
    scenarios, as scripts/level_acceleration_probe.py does. Ctrl-C ends it with one line saying what
    was written (exit 130)."""
    p = parser()
    args = p.parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    if args.controller == "stand_still" and args.checkpoint:
        p.error("--controller stand_still takes no --checkpoint")
    if args.controller != "stand_still" and not args.checkpoint:
        p.error("give --checkpoint PATH (a LAS-MP policy, or an R-S policy with --controller rs|rs_oracle)")
    claimed: list[od.ResultDir] = []
    evaluation = run_suite if args.suite else run_xi
    table = dataclasses.replace(ERRORS, interrupted=lambda: od.interrupted(claimed[0] if claimed else None))
    return errors.run(lambda: evaluation(args, p, motions, claimed), table)


# what a user can meet, each said in one line (`lasmp.io.errors`): an output, a benchmark, a
# trajectory file or a checkpoint it cannot use (2), said before any episode is played; a result it
# cannot write is said by `od.publish` (1), after the metrics it could not save. A Ctrl-C says what
# was written (130: `main`).
INPUT_ERRORS = (CheckpointError, od.OutDirError, bm.BenchmarkFileError, trj.TrajectoryFileError)
ERRORS = errors.ErrorTable(bad_input=INPUT_ERRORS)


def run_xi(args, p, motions, claimed: list) -> int:
    """The benchmark Xi_eval (or --trajectories with its robots)."""
    if motions is not None:
        p.error("motions need --suite")
    for flag, value in (
        ("--scenarios", args.scenarios),
        ("--robots-per-scenario", args.robots_per_scenario),
        ("--platform-drive", args.platform_drive),
    ):
        if value is not None:
            p.error(f"{flag} needs --suite")
    if args.plot_estimates and args.controller is not None:
        p.error("--plot-estimates needs --checkpoint (a policy with estimators)")
    # the output before the benchmark, the policy and the physics: a refusal costs seconds
    with od.claim_out(args, Path("eval"), claimed) as out:
        bench = load_or_make_benchmark(args.benchmark)
        if args.trajectories is not None:
            bench = dataclasses.replace(bench, trajectories=trj.load(args.trajectories))
        total = len(bench.trajectories)
        if args.num_trajectories is None:
            args.num_trajectories = total
        if not 1 <= args.num_trajectories <= total:
            p.error(f"--num-trajectories must be in [1, {total}], got {args.num_trajectories}")
        if args.mirror is not None and args.mirror > args.num_trajectories:
            p.error(
                f"--mirror must be in [1, {args.num_trajectories}] (the episodes played), got {args.mirror}"
            )
        out.check_space(args.num_trajectories + (args.mirror or 0))
        checkpoint = od.checkpoint_file(args.checkpoint)
        env, controller, policy, method = build(args, checkpoint=checkpoint)
        inputs = od.provenance(args, checkpoint, args.benchmark)
        return evaluate_xi(args, out, bench, env, controller, policy, method, inputs)


def evaluate_xi(args, out: od.ResultDir, bench, env, controller, policy, method: str, inputs: dict) -> int:
    run = run_benchmark(
        env, controller, bench, args.num_trajectories, policy=policy, trace=args.plot_estimates
    )
    episodes = run["episodes"]
    writers = []
    mirror = None
    if args.mirror is not None:
        twins = MirroredBenchmark(bench, env.nominal_com_y_m, env.cfg.init_state)
        mirrored = run_benchmark(env, controller, twins, args.mirror)["episodes"]
        mirror_table = ep.episode_table(twins, mirrored, None)
        writers.append((ep.MIRROR_EPISODES_FILE, lambda path: ep.write_csv(path, mirror_table)))
        mirror = mirror_report(episodes, mirrored)
    probe = None
    if not args.no_platform_probe:
        probe = pp.probe_platform(env.cfg, bench, args.num_trajectories, env.num_envs)
    table = ep.episode_table(bench, episodes, probe)
    writers.insert(0, (ep.EPISODES_FILE, lambda path: ep.write_csv(path, table)))
    result = {
        "method": method,
        "benchmark": str(args.trajectories or args.benchmark),
        **inputs,
        "num_episodes": args.num_trajectories,
        "std_over": f"{min(NUM_BATCHES, args.num_trajectories)} consecutive equal batches of episodes",
        "metrics": summarize(episodes, NUM_BATCHES, ALL_METRICS),
        "gait": summarize_gait(episodes),
        "h_des_p_m": metric_h_des_p_m(env.plf_top_m),
        "mean_episode_steps": float(episodes["steps"].mean()),
        "forced_episodes": None if probe is None else int(pp.count_forced(probe)),
        "wall_time_s": run["wall_time_s"],
        # what `python -m lasmp.eval.regenerate` replays, and the records it must give again
        "batch_envs": args.batch_envs,
        "torch_threads": args.torch_threads,
        ep.DIGEST_KEY: {ep.EPISODES_FILE: ep.table_digest(table)},
    }
    if mirror is not None:
        result[ep.DIGEST_KEY][ep.MIRROR_EPISODES_FILE] = ep.table_digest(mirror_table)
    if "estimator" in run:
        result["estimator"] = run["estimator"]
    if mirror is not None:
        result["mirror"] = mirror
    paper = paper_row(paper_key(args.controller, method))
    if paper is not None:
        result["paper"] = paper
    if args.plot_estimates and run.get("trace") is not None and len(policy.estimation_names):
        trace = run["trace"]
        writers.append(
            (od.ESTIMATES_PLOT, lambda path: plot_estimates(trace, policy.estimation_names, env.dt_s, path))
        )
        result["estimates_plot_episode"] = trace["episode"]
    return od.publish(out, markdown(result), [*od.result_writers(result, markdown), *writers])


def run_suite(args, p, motions, claimed: list) -> int:
    """`--suite real_motion`: every scenario (or `motions`) with the benchmark's first R robots
    (lasmp.eval.real_motion)."""
    from lasmp.eval.real_motion import suite as rm

    for flag, value in (
        ("--trajectories", args.trajectories),
        ("--num-trajectories", args.num_trajectories),
        ("--plot-estimates", args.plot_estimates or None),
        ("--no-platform-probe", args.no_platform_probe or None),
        ("--mirror", args.mirror),
    ):
        if value is not None:
            p.error(f"{flag} does not apply to --suite")
    drive = rm.DEFAULT_DRIVE if args.platform_drive is None else args.platform_drive
    robots = rm.DEFAULT_ROBOTS_PER_SCENARIO if args.robots_per_scenario is None else args.robots_per_scenario
    if motions is not None and args.scenarios:
        p.error("give --scenarios or motions, not both")
    with errors.bad_input_from(ValueError):  # an unknown scenario
        if motions is None:
            names = rm.scenario_names(args.scenarios)  # checked before anything is made
        out = od.claim_out(args, Path("eval") / rm.SUITE_NAME, claimed)
    with out:
        with errors.bad_input_from(ValueError):  # a motion, benchmark or checkpoint the suite cannot play
            if motions is None:
                motions = rm.build_motions(names)
            names = [m.name for m in motions]
            bench = load_or_make_benchmark(args.benchmark)
            episodes = rm.make_episodes(motions, bench.robots, robots)
            duration_s = max(m.duration_s for m in motions)
            extra = rm.env_overrides(duration_s, drive)
            args.num_trajectories = episodes.num_episodes
            out.check_space(episodes.num_episodes)
            checkpoint = od.checkpoint_file(args.checkpoint)
            env, controller, policy, method = build(args, extra, checkpoint)
            inputs = od.provenance(args, checkpoint, args.benchmark)
        tracking = rm.platform_tracking(episodes, eval_env_overrides(len(names), args.seed, extra))
        run = run_benchmark(env, controller, episodes, episodes.num_episodes, policy=policy)
        per_episode = run["episodes"]
        result = rm.suite_result(method, episodes, motions, run, tracking, drive, args.benchmark, inputs)
        table = rm.episode_table(episodes, per_episode, env.cfg.init_state)
        episodes_file = (ep.EPISODES_FILE, lambda path: ep.write_csv(path, table, rm.EPISODE_COLUMNS))
        return od.publish(out, rm.markdown(result), [*od.result_writers(result, rm.markdown), episodes_file])
