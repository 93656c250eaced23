"""Play a trained LAS-MP policy: the logic behind `play.py`.

    python play.py --checkpoint PATH [--num-envs 1] [--steps 500] [--seed S] [--video out.mp4]
                   [--snapshots out.png] [--viewer] [--export onnx --out DIR] [--force]
                   [--trajectories FILE | --scenario NAME | --benchmark-episode K [--benchmark FILE]]

The env and the policy are rebuilt from the checkpoint's own config (never today's defaults);
only the number of envs, the seed and (optionally) the trajectory file are overridden. The policy
runs in deployment mode: its inputs are o_t and the history o^H only (the estimators replace the
privileged groups), with deterministic (mean) actions.

Rendering (`lasmp.render`) shows env 0 in a visual-only world (ground grid, sky, pillars) from a
camera following the platform, with a caption (time, N, platform speed, collisions); it is
offscreen with `mujoco.Renderer`, which needs an OpenGL backend without a display:
`MUJOCO_GL=egl` (a GPU driver, or Mesa's EGL; the default set here) or, as a fallback,
`MUJOCO_GL=osmesa` with libosmesa6 installed (slow, software). `--video` also needs imageio and
imageio-ffmpeg (`pip install -e .[video]`). `--viewer` opens MuJoCo's interactive viewer and
needs a display (DISPLAY or WAYLAND_DISPLAY).

Every file it writes (video, snapshots, export) is checked and claimed before the env is built (its
extension, its directory; created exclusively, so it replaces no file without --force and no other
run writes it meanwhile) and is written whole or not at all.
A write that fails is one line naming the file (exit 1); a Ctrl-C says what was and was not written
(exit 130).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import shutil
from pathlib import Path

import torch

from lasmp.deploy import load_deploy_env
from lasmp.io.errors import ErrorTable, bad_input_from, run
from lasmp.io.inputs import InputError, int_arg, seed_arg
from lasmp.modules.export import deploy_metadata
from lasmp.render.outputs import EXPORT_FILES, Outputs, check_outputs, claim_outputs, export_into
from lasmp.render.renderer import (
    SNAPSHOT_COUNT,
    EnvRenderer,
    RenderError,
    VideoWriter,
    check_offscreen_gl,
    env_state,
    ffmpeg_exe,
    frame_caption,
    save_snapshots,
    snapshot_steps,
)
from lasmp.render.viewer import Viewer, has_display

DEFAULT_BENCHMARK = "benchmarks/xi_eval.npz"  # evaluate.py's; made on first use


# ---------------------------------------------------------------------------------------------
# Rollout
# ---------------------------------------------------------------------------------------------
class EpisodeStrip:
    """Env 0's states over the episode it is in when the run starts: what the snapshot strip shows.

    The strip spans that one episode, from its state at the start to its last before the reset
    (at the time limit or a collision) or the run's end. Where it ends is known only once it has
    (after the reset the env holds the next episode's first state), so every step's state (qpos,
    qvel: a few hundred bytes) and caption are kept, and the frames are rendered from them after
    the run.
    """

    def __init__(self, env) -> None:
        self.states: list[tuple] = []
        self.captions: list[str] = []
        self.times_s: list[float] = []
        self.ended = False
        self._keep(env)

    def _keep(self, env) -> None:
        self.states.append(env_state(env, 0))
        self.captions.append(frame_caption(env, 0))  # no collision yet: one would end the episode
        self.times_s.append(float(env.episode_length_buf[0]) * env.dt_s)

    def step(self, env, done: bool) -> None:
        """After a policy step: keep env 0's new state, unless its episode has just ended."""
        if done:
            self.ended = True
        elif not self.ended:
            self._keep(env)

    def picks(self, count: int = SNAPSHOT_COUNT) -> list[int]:
        """The kept states the strip shows: evenly spaced, the first and the last included."""
        return sorted(snapshot_steps(len(self.states), count))

    def frames(self, renderer) -> list:
        return [renderer.frame(self.captions[k], self.states[k]) for k in self.picks()]


def rollout(
    env, policy, steps: int, video=None, strip: EpisodeStrip | None = None, viewer=None, progress=None
) -> dict:
    """Run `steps` deterministic policy steps; return the summary counts.

    video: (EnvRenderer, VideoWriter) for a frame per step, captioned; strip: an EpisodeStrip that
    keeps env 0's states for the snapshots; viewer: a Viewer to sync each step (closing it ends the
    run); progress: an object whose `steps` is set after each step (what an interrupted run reports).
    """
    episodes = collisions = collisions_env0 = 0
    reward_sum = 0.0
    done_steps = 0
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(steps):
            obs, reward, dones, extras = env.step(policy(obs))
            done_steps += 1
            if progress is not None:
                progress.steps = done_steps
            collided = dones & ~extras["time_outs"]
            episodes += int(dones.sum())
            collisions += int(collided.sum())
            collisions_env0 += int(collided[0])
            reward_sum += float(reward.sum())
            if video:
                video[1].add(video[0].frame(frame_caption(env, collisions_env0)))
            if strip:
                strip.step(env, bool(dones[0]))
            if viewer and not viewer.sync():
                break
    return {
        "steps": done_steps,
        "episodes": episodes,
        "collisions": collisions,
        "mean_reward": reward_sum / max(done_steps * env.num_envs, 1),
    }


def summary_line(s: dict, num_envs: int) -> str:
    return (
        f"played {s['steps']} steps x {num_envs} envs: {s['episodes']} episodes ended, "
        f"{s['collisions']} collisions, mean reward per step {s['mean_reward']:.4f}"
    )


# ---------------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="play.py", description="Play (and render or export) a LAS-MP policy.")
    p.add_argument("--checkpoint", required=True, help="a checkpoint file or a run directory (its latest)")
    p.add_argument("--num-envs", type=int_arg(1), default=1)
    p.add_argument(
        "--steps", type=int_arg(0), default=None, help="policy steps (50 per second; default 500; 0: none)"
    )
    p.add_argument(
        "--seed",
        type=seed_arg,
        default=None,
        help="fresh random streams from this seed (other episodes); default: the checkpoint's own at the save",
    )
    p.add_argument("--video", help="write an mp4 of env 0 (camera following the platform)")
    p.add_argument(
        "--snapshots",
        help=f"write a PNG strip of {SNAPSHOT_COUNT} frames of env 0's first episode, its first state to its last "
        "(camera following the platform)",
    )
    p.add_argument("--viewer", action="store_true", help="show env 0 in MuJoCo's viewer (needs a display)")
    p.add_argument(
        "--export",
        choices=("onnx",),
        help=f"write the deployable policy to --out DIR ({' and '.join(EXPORT_FILES)}; docs/deploy.md)",
    )
    p.add_argument("--out", help="directory for --export")
    p.add_argument(
        "--force", action="store_true", help="overwrite an existing --video, --snapshots or --export file"
    )
    p.add_argument("--trajectories", help="a trajectory file (.npz) replayed instead of sampled trajectories")
    p.add_argument(
        "--scenario",
        help="a real-motion scenario (e.g. ship_sea_state_4, bus_stop_and_go) on the "
        "suite's close-tracking platform drive; --steps defaults to the whole scenario",
    )
    p.add_argument(
        "--benchmark-episode",
        type=int_arg(0),
        default=None,
        metavar="K",
        help="play benchmark episode K (its trajectory and robot; see --benchmark) and the ones after",
    )
    p.add_argument(
        "--benchmark",
        default=None,
        help=f"the benchmark file for --benchmark-episode (default {DEFAULT_BENCHMARK})",
    )
    return p


def refuse_conflicts(parser: argparse.ArgumentParser, args) -> None:
    """Options that cannot go together, or one that would be ignored, as a parser error (exit 2).

    A benchmark episode is a trajectory and a robot of its own, so --trajectories would be ignored
    and --scenario would play a hybrid (the scenario's drive, the benchmark's motion)."""
    if args.export and not args.out:
        parser.error("--export needs --out DIR")
    if args.out and not args.export:
        parser.error("--out is the directory of --export; give --export onnx too")
    if args.scenario and args.trajectories:
        parser.error("give --scenario or --trajectories, not both")
    if args.benchmark_episode is not None and (args.trajectories or args.scenario):
        which = "--trajectories" if args.trajectories else "--scenario"
        parser.error(
            f"--benchmark-episode plays the benchmark's own trajectories: give it or {which}, not both"
        )
    if args.benchmark is not None and args.benchmark_episode is None:
        parser.error("--benchmark is read only with --benchmark-episode K")
    if args.video and args.steps == 0:
        parser.error("--video needs --steps >= 1 (a video of no frames is not a video)")


def scenario_file(name: str) -> tuple[str, dict]:
    """(trajectory file, env overrides) that play real-motion scenario `name` as the suite does."""
    import tempfile

    from lasmp.envs.trajectories import save
    from lasmp.eval.real_motion import suite as rm
    from lasmp.motions.motion import to_trajectories

    (motion,) = rm.build_motions([name])
    path = Path(tempfile.mkdtemp(prefix="lasmp-scenario-")) / f"{name}.npz"
    save(path, to_trajectories([motion]))
    return str(path), rm.env_overrides(motion.duration_s, rm.DEFAULT_DRIVE)


def use_benchmark_episodes(env, path: str, first: int) -> None:
    """Reset `env` into benchmark episodes first, first + 1, ... (trajectory k with robot k mod R)."""
    from lasmp.eval.build import load_or_make_benchmark
    from lasmp.eval.run import BenchmarkSource

    # the default benchmark is made on first use, as evaluate.py does
    bench = load_or_make_benchmark(Path(path))
    if not 0 <= first < len(bench.trajectories):
        raise ValueError(f"--benchmark-episode must be in [0, {len(bench.trajectories) - 1}], got {first}")
    source = BenchmarkSource(bench, len(bench.trajectories), env.num_envs)
    source.next_episode = first
    env.episode_source = source
    env.reset()


# what a user can meet, each said in one line (`lasmp.io.errors`). Bad input (2) is said before the
# rollout: a file this run cannot write (`check_files`), a checkpoint, trajectory file, scenario or
# benchmark episode it cannot play (`play`), a renderer it cannot have; a write that fails once the
# run has begun (AtomicWriteError: a full disk, ...) names its file (1). A Ctrl-C says what was and
# was not written (130: `main`).
ERRORS = ErrorTable(bad_input=(InputError, RenderError), cannot_go_on=(OSError,))


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    refuse_conflicts(parser, args)
    checked: list[Outputs] = []  # this run's files, once checked: what it wrote, said when it ends early

    def work() -> int:
        if args.viewer and not has_display():
            raise InputError(
                "--viewer needs a display (DISPLAY or WAYLAND_DISPLAY is unset); use --video or --snapshots "
                "to render offscreen"
            )
        outputs, claims = check_files(args)
        checked.append(outputs)
        with claims:  # an unwritten claim is removed when the run ends, however it ends
            return play(args, outputs)

    def interrupted() -> str:
        return (checked[0] if checked else Outputs([])).interrupted()

    def remove_new_empty_dirs() -> None:  # a failed or interrupted run leaves no directory it made empty
        for outputs in checked:
            outputs.remove_new_empty_dirs()

    return run(work, dataclasses.replace(ERRORS, interrupted=interrupted), on_exit=remove_new_empty_dirs)


def check_files(args) -> tuple[Outputs, contextlib.ExitStack]:
    """Every file this run writes, checked and claimed before the env is built, with what writing
    them needs (ffmpeg for the video, offscreen OpenGL): (what the run has written, the claims). A
    file it cannot write is bad input here (a file there without --force, a read-only directory),
    not a failed write."""
    with bad_input_from(OSError):
        outputs = Outputs(check_outputs(args))
        if args.video:
            ffmpeg_exe()
        if args.video or args.snapshots:
            check_offscreen_gl()
        return outputs, claim_outputs(args)  # last: the checks above leave nothing behind


def evaluation_episodes(task: str) -> dict:
    """The env overrides that make a moving-platform checkpoint's episodes those evaluation plays: a
    training run's hold past T is training's alone. Other tasks (R-S on rough terrain) have no hold."""
    return {"trajectory": {"hold_s": 0.0}} if task == "moving_platform" else {}


def play(args, outputs: Outputs) -> int:
    """main's work once its options and files are checked: load, export, roll out, write. A value
    the load refuses (the checkpoint, the trajectory file, the scenario, the benchmark episode) is
    bad input, as is one the export refuses; `ERRORS` says the rest."""
    with bad_input_from(ValueError):  # CheckpointError, ConfigError, TrajectoryFileError, ...
        trajectories, overrides = args.trajectories, evaluation_episodes
        if args.scenario:
            trajectories, overrides = scenario_file(args.scenario)
        try:
            env, policy, cfg, data = load_deploy_env(
                args.checkpoint, args.num_envs, args.seed, trajectories, overrides
            )
        finally:
            if args.scenario:  # the env holds the motion in memory; the file was only the way in
                shutil.rmtree(Path(trajectories).parent, ignore_errors=True)
        steps = args.steps
        if steps is None:
            # the last frame before the reset
            steps = env.max_episode_length - 1 if args.scenario else 500
        if args.benchmark_episode is not None:
            use_benchmark_episodes(env, args.benchmark or DEFAULT_BENCHMARK, args.benchmark_episode)
    # a run directory means its newest checkpoint: say which file that was
    print(f"loaded {data['path']} (iteration {data['iter']}, task {cfg.task})", flush=True)

    if args.export:
        # a policy the export cannot take (the R-S baseline's command input); a failed write is not that
        with bad_input_from(ValueError, prefix="--export: "):
            metadata = deploy_metadata(policy, cfg, data["iter"], Path(data["path"]).name)
            path, sidecar = files = export_into(policy, Path(args.out), metadata)
        outputs.written += files
        print(f"exported {args.export} policy to {path} (metadata in {sidecar})", flush=True)

    closers = []
    video = viewer = shots = None
    strip = EpisodeStrip(env) if args.snapshots else None
    outputs.total_steps = steps
    try:
        if args.video or args.snapshots:  # one renderer (camera following the platform) serves both
            renderer = EnvRenderer(env, follow=True)
            closers.append(renderer)
        if args.video:
            writer = VideoWriter(args.video, fps=1.0 / env.dt_s)
            video = (renderer, writer)
        if args.viewer:
            viewer = Viewer(env)
            closers.append(viewer)
        outputs.steps = 0
        stats = rollout(env, policy, steps, video, strip, viewer, progress=outputs)
        if video:
            writer.close()  # the finished file renamed into place
            outputs.written.append(Path(args.video))
        if strip:
            shots = strip.frames(renderer)
    finally:
        if video and Path(args.video) not in outputs.written:
            writer.abort()  # a failed or interrupted run: no partial video
        for c in reversed(closers):
            c.close()
    if stats["steps"] or not args.export:  # an export alone (--steps 0) played nothing: no line about it
        print(summary_line(stats, env.num_envs), flush=True)
    if video:
        print(f"wrote {video[1].frames} frames to {args.video}", flush=True)
    if shots:
        save_snapshots(shots, args.snapshots)
        outputs.written.append(Path(args.snapshots))
        first, last = strip.times_s[0], strip.times_s[-1]
        print(
            f"wrote {len(shots)} snapshots of env 0's episode, t {first:.2f} to {last:.2f} s, to {args.snapshots}",
            flush=True,
        )
    return 0
