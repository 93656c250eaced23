"""Where a LAS-MP policy's deployment gap comes from: collisions on a still platform per input source.

The policy plays 20 s on a platform that does not move (the real-motion suite's close drive), with
the checkpoint's own robot randomization, in six input modes: everything estimated (deployment),
and the estimates with one part replaced by the truth: the explicit estimates x_exp (contacts and
velocities), the contacts only, the velocities only (body and platform velocities, which also
rebuild u_aln), the implicit latent l_imp, and x_exp plus l_imp (= the privileged inputs); and one
mode that asks whether the policy uses its explicit estimates at all: each env is fed another env's
estimates x_exp (a fixed derangement of the envs; its own l_imp and proprioception). Prints one JSON
object: the share of episodes that end in a collision or fall, per mode.

With `--benchmark-episodes K`, the platform plays the first K trajectories of Xi_eval instead
(one episode per env, the env's default platform drive, robots drawn from the testing ranges):
where estimation costs the moving-platform task.

    python bench/deployment_gap.py --checkpoint runs/lasmp_v2_seed0 --num-envs 128
    python bench/deployment_gap.py --checkpoint runs/lasmp_v2_seed0 --benchmark-episodes 256 --modes "" v xl
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import torch

from lasmp.deploy import load_deploy_env
from lasmp.envs import trajectories as trj
from lasmp.eval import benchmark as bm
from lasmp.eval.real_motion import suite as rm
from lasmp.modules.obs_groups import GYRO_Z_COL
from lasmp.modules.policy import alignment_from_estimates
from lasmp.motions.motion import Motion, time_grid, to_trajectories

N_CONTACTS = 4  # x_exp = [contacts (4), v_body_b (3), v_plf_b (3), omega_plf_b (3)]
MODES = {
    "deployment (all estimated)": "",
    "true x_exp": "x",
    "true contacts": "c",
    "true velocities": "v",
    "true l_imp": "l",
    "privileged (true x_exp and l_imp)": "xl",
    "another env's x_exp": "s",
}


def derangement(n: int, seed: int = 0) -> np.ndarray:
    """A permutation of range(n) that moves every index: env i reads env perm[i]'s estimates."""
    if n < 2:
        raise ValueError(f"another env's estimates need at least 2 envs, got {n}")
    perm = np.random.default_rng(seed).permutation(n)
    return np.roll(perm, 1)[np.argsort(perm)]


BENCHMARK_ENV = {"domain_rand": {"split": "test"}, "curriculum": {"enabled": False}}  # as evaluate.py's


class MixedInputs:
    """Mixed into the checkpoint's actor (lasmp.deploy's `mixin`): its estimates with the parts that
    `truth` names replaced, read from `true_obs` (the privileged groups of the observations the actor
    was last called on); "s" feeds env i the estimates of env `other[i]`."""

    truth: str = ""
    true_obs = None
    other: torch.Tensor | None = None

    def get_latent(self, obs, *args, **kwargs):
        self.true_obs = obs  # every call reads its own step's truth; callers need not set it
        return super().get_latent(obs, *args, **kwargs)

    def _estimated_inputs(self, o, history_n):
        x_hat, l_hat, _ = super()._estimated_inputs(o, history_n)
        x_true = self.true_obs["priv_explicit"][:, : x_hat.shape[1]]
        if "x" in self.truth:
            x_hat = x_true
        if "c" in self.truth:
            x_hat = torch.cat([x_true[:, :N_CONTACTS], x_hat[:, N_CONTACTS:]], 1)
        if "v" in self.truth:
            x_hat = torch.cat([x_hat[:, :N_CONTACTS], x_true[:, N_CONTACTS:]], 1)
        if "s" in self.truth:
            x_hat = x_hat[self.other]
        if "l" in self.truth:
            l_hat = self.encoder(self.true_obs["priv_implicit"])
        u_hat = alignment_from_estimates(x_hat, o[:, GYRO_Z_COL]) if self.use_alignment else None
        return x_hat, l_hat, u_hat


def mixed_policy(checkpoint: str, path: str, duration_s: float | None, n: int, seed: int | None, truth: str):
    """(env, policy): the checkpoint's policy reading the inputs of mode `truth` (MixedInputs), and
    its env of n envs; duration_s None: the trajectory file is benchmark episodes, played with the
    env's own episode length and drive."""
    overrides = BENCHMARK_ENV if duration_s is None else rm.env_overrides(duration_s, "close")
    env, pol, _, _ = load_deploy_env(
        checkpoint, num_envs=n, seed=seed, trajectories=path, env_overrides=overrides, mixin=MixedInputs
    )
    pol.truth = truth
    pol.other = torch.as_tensor(derangement(n)) if "s" in truth else None
    return env, pol


def collision_rate(
    checkpoint: str, path: str, duration_s: float | None, n: int, seed: int | None, truth: str
) -> float:
    """Share of the n envs' first episodes that end in a collision or fall (`mixed_policy`'s)."""
    env, pol = mixed_policy(checkpoint, path, duration_s, n, seed, truth)
    obs = env.get_observations()
    ended = np.zeros(n, bool)
    collided = np.zeros(n, bool)
    with torch.inference_mode():
        for _ in range(env.max_episode_length):
            obs, _, done, extras = env.step(pol(obs))
            done = done.numpy()
            collided |= done & ~extras["time_outs"].numpy() & ~ended
            ended |= done
    return float(collided.mean())


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--num-envs", type=int, default=128)
    ap.add_argument("--duration-s", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=None, help="default: the checkpoint's own random streams")
    ap.add_argument(
        "--modes",
        nargs="+",
        choices=list(MODES.values()),
        default=list(MODES.values()),
        help="truth substituted: '' none, x, c, v, l, xl; s: another env's x_exp (default: all seven)",
    )
    ap.add_argument(
        "--benchmark-episodes",
        type=int,
        default=None,
        help="play the first K Xi_eval trajectories (one per env) instead of a still platform",
    )
    ap.add_argument("--benchmark", default="benchmarks/xi_eval.npz")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "trajectories.npz")
        if args.benchmark_episodes is None:
            n, duration_s = args.num_envs, args.duration_s
            t = time_grid(duration_s)
            trj.save(path, to_trajectories([Motion("still", t, np.zeros((len(t), 6)))]))
            out = {"checkpoint": args.checkpoint, "num_envs": n, "duration_s": duration_s}
        else:
            bench = bm.load(args.benchmark)
            if not 1 <= args.benchmark_episodes <= len(bench.trajectories):
                ap.error(f"--benchmark-episodes must be in [1, {len(bench.trajectories)}]")
            n, duration_s = args.benchmark_episodes, None
            trj.save(path, bench.trajectories.subset(np.arange(n)))
            out = {"checkpoint": args.checkpoint, "benchmark": args.benchmark, "episodes": n}
        if "s" in args.modes and n < 2:
            ap.error("mode s (another env's x_exp) needs at least 2 envs or episodes")
        out["collision_rate"] = {
            label: collision_rate(args.checkpoint, path, duration_s, n, args.seed, truth)
            for label, truth in MODES.items()
            if truth in args.modes
        }
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
