"""The ranges of the training settings (`lasmp.config.train`: policy, algo, runner, torch_threads) and the
reason for each: a physical or computational one (`lasmp.config.checks.Bound`). The env settings' ranges sit
beside their schemas (`lasmp/config/base.py`, `lasmp/envs/<task>/cfg.py`)."""

from __future__ import annotations

from lasmp.config.checks import Bound

MAX_VALIDATION_EPISODES = 2_000  # the validation benchmark's size (lasmp.eval.benchmark.VALIDATION)

# a loss term's weight against PPO's surrogate, of order 1
LOSS_WEIGHT = Bound(0, 100, "a loss weight against the PPO surrogate's, of order 1")

MAX_LAYERS = 8
WIDTH = Bound(1, 4096, "units: a 4096 x 4096 layer with its gradient and Adam's moments is 256 MiB")
POLICY_BOUNDS = {
    "actor_hidden_dims": WIDTH,
    "critic_hidden_dims": WIDTH,
    "encoder_hidden_dims": WIDTH,
    "latent_dim": Bound(1, 256, "the size of l_imp, which encodes x_imp's 29 values"),
    "estimator_mlp_dim": Bound(1, 1024, "applied to every step of the history, for every sample"),
    "estimator_channels": Bound(1, 1024, "channels of the convolutions over the history, for every sample"),
    "init_noise_std": Bound(0, 10, "action units: 10 is 2.5 rad at the default scale", open_lo=True),
}

ITERATIONS = Bound(0, 1_000_000, "iterations: a million is months of training")
LEARNING_RATE = Bound(0, 1, "Adam's step: above 1 it diverges at once", open_lo=True)
EPOCHS = Bound(1, 100, "passes over each rollout: long before 100, PPO's clip stops every sample")
ALGO_BOUNDS = {
    "learning_rate": LEARNING_RATE,
    "num_learning_epochs": EPOCHS,
    "clip_param": Bound(0, 1, "PPO's ratio clip 1 +- clip_param: at 1 its low side is 0", open_lo=True),
    "gamma": Bound(0, 1, "a discount", open_lo=True),
    "lam": Bound(0, 1, "GAE's lambda"),
    "value_loss_coef": LOSS_WEIGHT,
    "entropy_coef": Bound(0, 1, "the entropy bonus' weight: at 1 it outweighs the surrogate"),
    "entropy_decay_iterations": ITERATIONS,
    "max_grad_norm": Bound(0, 1000, "the gradient's norm clip: at 1000 it clips nothing", open_lo=True),
    "desired_kl": Bound(0, 1, "nats between successive policies, schedule=adaptive", open_lo=True),
    "roa_lambda": LOSS_WEIGHT,
    "estimator_learning_rate": LEARNING_RATE,
    "estimator_epochs": EPOCHS,
    "estimate_rollout_every": ITERATIONS,
    "estimate_rollout_start": ITERATIONS,
}

RUNNER_BOUNDS = {
    "num_steps_per_env": Bound(1, 10_000, "steps per env and iteration: 10,000 are 20 episodes of 10 s"),
    "max_iterations": ITERATIONS,
    "save_interval": Bound(1, 1_000_000, "iterations: a million is months of training"),
    "keep_full": Bound(1, 1000, "full checkpoints kept, each the whole learner's state"),
    "max_fault_fraction": Bound(0, 1, "a fraction of an iteration's env-steps; 1: never stop"),
    "validation_interval": ITERATIONS,
    "validation_episodes": Bound(1, MAX_VALIDATION_EPISODES, "the validation benchmark's episodes"),
}

THREADS = Bound(0, 1024, "torch's CPU threads, 0 = torch's default: more than any machine has")
