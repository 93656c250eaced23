"""Training configuration: schemas for the policy, the algorithm and the runner, registered in
Hydra's ConfigStore as the base of `cfg/config.yaml`, and their translation to rsl_rl's dict.

Each task's env schema is registered too, as an option of the config group `env` named after the
task (`env: moving_platform` in `cfg/config.yaml`, overridden by `cfg/task/rough_static.yaml`), so
`env.*` overrides are typed like the rest. Hydra type-checks every override against these dataclasses
and refuses unknown keys, naming them; `validate_train_cfg` then checks value ranges, naming the field.
"""

from __future__ import annotations

import importlib.util
import os
from dataclasses import dataclass, field, is_dataclass
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from lasmp.algo.precision import PRECISIONS
from lasmp.algo.symmetry import supports_mirror
from lasmp.config.base import merge_env_cfg
from lasmp.config.bounds import (
    ALGO_BOUNDS,
    LOSS_WEIGHT,
    MAX_LAYERS,
    POLICY_BOUNDS,
    RUNNER_BOUNDS,
    THREADS,
)
from lasmp.config.checks import Bound, ConfigError, check_config, check_seed_key
from lasmp.envs import registry
from lasmp.envs.registry import env_schema
from lasmp.modules.obs_groups import EXPLICIT_SELECTIONS

ACTOR_CLASS = "lasmp.modules.policy:LasmpActor"
CRITIC_CLASS = "rsl_rl.models:MLPModel"
ALGORITHM_CLASS = "lasmp.algo.ppo_roa:PPOROA"
# the tasks of the task registry (lasmp/envs/registry.py), also their options in the Hydra config group `env`
TASKS = tuple(registry.TASKS)
# runner.logger -> (rsl_rl's writer class, the package it imports, the extra that installs it); docs/logging.md
LOGGERS: dict[str, tuple[str, str, str] | None] = {
    "tensorboard": None,  # rsl_rl's default: torch's SummaryWriter
    "wandb": ("WandbLogWriter", "wandb", "wandb"),
    "neptune": ("NeptuneLogWriter", "neptune", "neptune"),
}


@dataclass
class PolicyCfg:
    name: str = "lasmp"  # the ablation's name, for run directories and reports
    actor_hidden_dims: list[int] = field(default_factory=lambda: [512, 256, 128])  # 4 layers with the output
    critic_hidden_dims: list[int] = field(default_factory=lambda: [512, 256, 128])
    activation: str = "elu"
    latent_dim: int = 16  # size of l_imp (ours)
    encoder_hidden_dims: list[int] = field(default_factory=lambda: [64])
    estimator_mlp_dim: int = 32
    estimator_channels: int = 32
    use_alignment: bool = True  # the alignment command u_aln is an actor input
    explicit: str = "all"  # explicit estimator outputs: all | no_platform | none
    history_input: bool = False  # the raw observation history is an actor input
    command_input: bool = False  # a velocity command (group `command`) is an actor input (R-S baseline)
    # (ours) rsl_rl's is 1.0: the curriculum judges the sampled rollouts, so the noise counts against
    # the level (docs/method.md#curriculum-randomization-episodes)
    init_noise_std: float = 0.5

    BOUNDS = POLICY_BOUNDS
    CHOICES = {"explicit": EXPLICIT_SELECTIONS}

    def check_rules(self, p: str) -> None:
        if self.use_alignment and self.explicit != "all":
            raise ConfigError(
                f"{p}.use_alignment needs {p}.explicit=all (the command is built from platform estimates)"
            )
        for name in ("actor_hidden_dims", "critic_hidden_dims", "encoder_hidden_dims"):
            dims = getattr(self, name)
            if not 1 <= len(dims) <= MAX_LAYERS:
                raise ConfigError(
                    f"{p}.{name} must list 1 to {MAX_LAYERS} hidden layer widths (rsl_rl's MLP needs one), "
                    f"got {list(dims)}"
                )


@dataclass
class SymmetryCfg:
    """rsl_rl's `symmetry_cfg` (ours, LAS-MP+): learn a left-right symmetric policy with the sagittal
    mirror (lasmp/algo/symmetry.py). Both off: no symmetry (the paper's recipe)."""

    use_data_augmentation: bool = False  # append each mini-batch's mirror images to it
    use_mirror_loss: bool = False  # penalize pi(mirror(o)) != mirror(pi(o))
    mirror_loss_coeff: float = 0.0

    @property
    def enabled(self) -> bool:
        return self.use_data_augmentation or self.use_mirror_loss

    BOUNDS = {"mirror_loss_coeff": LOSS_WEIGHT}

    def check_rules(self, p: str) -> None:
        if self.use_mirror_loss and self.mirror_loss_coeff == 0:
            raise ConfigError(f"{p}.mirror_loss_coeff must be > 0 with use_mirror_loss, got 0")


@dataclass
class AlgoCfg:
    learning_rate: float = 1e-3
    # (ours) LAS-MP+'s: two passes over a rollout that the mirror augmentation doubles, at about the
    # learning of five and half the learner's time (docs/performance.md#the-learner-with-the-mirror-
    # augmentation); recipe=paper and the R-S task keep rsl_rl's 5
    num_learning_epochs: int = 2
    num_mini_batches: int = 4
    clip_param: float = 0.2
    gamma: float = 0.99
    lam: float = 0.95
    value_loss_coef: float = 1.0
    # (ours) a small bonus (rsl_rl's is 0.01, the paper names none): enough to keep the action std from
    # collapsing, too little to pull it up (docs/results.md#the-entropy-bonus)
    entropy_coef: float = 0.003
    # (ours) the bonus falls linearly from entropy_coef to 0 over this many iterations, then stays 0;
    # 0: constant, as rsl_rl's (docs/results.md#the-entropy-bonus)
    entropy_decay_iterations: int = 0
    max_grad_norm: float = 1.0
    desired_kl: float = 0.01
    schedule: str = "adaptive"
    # λ of L_imp (docs/method.md#learning-ppo-with-regularized-online-adaptation-lasmpalgo)
    roa_lambda: float = 0.2
    estimator_learning_rate: float = 1e-3  # (ours) the estimators' own Adam
    estimator_epochs: int = 1  # (ours) ROA passes over each rollout
    # (ours) from iteration estimate_rollout_start on, every estimate_rollout_every-th iteration's
    # rollout and PPO update act on the estimators' detached outputs, as at deployment, to close the
    # train/deploy gap; 0: never, the paper's literal reading
    # (docs/method.md#training-on-the-estimates-ours-a-departure-from-the-papers-literal-reading)
    estimate_rollout_every: int = 1
    estimate_rollout_start: int = 100
    # (ours) how the learner computes (lasmp/algo/precision.py): auto = bfloat16 autocast, the fused
    # Adam and compiled MLPs, each where it works and pays here, the start-up line saying why not;
    # float32 = none of them (the same learner wherever it runs: a seeded run repeats its curve);
    # bfloat16 = the autocast forced (docs/performance.md#the-learners-precision-algoprecision)
    precision: str = "auto"
    # per-part overrides of precision (null: as precision decides). fused_adam: both Adams as one
    # fused kernel; use_mixed_precision: rsl_rl's bfloat16 autocast of the PPO update's forward pass,
    # extended to the ROA pass; compile_mlps: torch.compile in place the actor's and critic's MLPs, the
    # implicit encoder's and the history estimators (the first iteration compiles; a CPU needs a C++
    # compiler; checkpoints are unchanged). All three false: the float32 learner, whatever precision says
    fused_adam: bool | None = None
    use_mixed_precision: bool | None = None
    compile_mlps: bool | None = None
    symmetry_cfg: SymmetryCfg = field(default_factory=SymmetryCfg)
    # (ours; the paper does not say) an episode cut by its time limit, not by a fall, adds γ·V(s_T)
    # to its last reward (rsl_rl's truncation bootstrap); false: the time limit ends the return as a
    # fall does, a switch to measure what the bootstrap does to the late falls
    # (docs/method.md#las-mp-the-options-that-depart-from-the-papers-recipe-ours)
    bootstrap_time_outs: bool = True

    BOUNDS = ALGO_BOUNDS
    CHOICES = {"precision": PRECISIONS}


@dataclass
class RunnerCfg:
    num_steps_per_env: int = 12  # 0.24 s of data per env per iteration, as in the paper
    # on resume, the iterations to add (rsl_rl's convention): a run saved at model_34.pt resumed with
    # max_iterations=35 runs iterations 35-69
    max_iterations: int = 1500
    save_interval: int = 100
    # (ours) the newest full checkpoints model_<N>.pt kept in the run directory; each older save becomes
    # its policy checkpoint policy_<N>.pt, which plays and evaluates but cannot resume: a laptop keeps
    # a long run (docs/usage.md#checkpoints-lasmpalgocheckpoint)
    keep_full: int = 2
    log_dir: str | None = None  # default: logs/<task>/<policy>/<date_time>
    check_for_nan: bool = True
    # stop when more than this fraction of an iteration's env-steps fault (the physics diverges); 1: never
    max_fault_fraction: float = 0.5
    # where the scalars go (docs/logging.md): tensorboard | wandb | neptune. wandb and neptune write the
    # TensorBoard files too; each needs its extra (pip install -e ".[wandb]" / ".[neptune]")
    logger: str = "tensorboard"
    wandb_project: str = "lasmp"  # the W&B project (the entity: $WANDB_USERNAME, else your default)
    neptune_project: str = "lasmp"  # the Neptune project, under the workspace $NEPTUNE_USERNAME
    # (ours) in-training validation (lasmp/eval/validation.py): after every validation_interval-th iteration
    # (e.g. 49, 99, ... at 50) the policy plays the validation benchmark's first validation_episodes episodes;
    # the run keeps policy_best.pt and validation.json. 0: never. The cost at the default:
    # docs/performance.md#in-training-validation
    validation_interval: int = 50
    validation_episodes: int = 256

    BOUNDS = RUNNER_BOUNDS

    def check_rules(self, p: str) -> None:
        validate_logger(self)


@dataclass
class TrainCfg:
    task: str = "moving_platform"
    seed: int = 0
    # where the learner runs, and the physics with env.backend=warp (cpu backend: the CPU)
    device: str = "cpu"
    torch_threads: int = 0  # CPU threads of torch for the learner; 0 = torch's default (all cores)
    resume: str | None = None  # a full checkpoint file or a run directory (its latest model_<N>.pt)
    # on resume, start every env's episode anew instead of restoring the envs' running state: needed
    # when env.num_envs differs from the checkpoint's (the resume is then not exact)
    resume_drop_env_state: bool = False
    # (ours) a new run from a checkpoint's weights (any form: full, policy, light), with fresh optimizers:
    # what goes on from a committed policy when the run's full checkpoint is lost (lasmp/cli/warm_start.py)
    warm_start: str | None = None
    # the task's env config, env_schema(task). Hydra composes it from the `env` group (typed: unknown keys
    # fail naming them); a plain dict (a checkpoint's saved config) is built with the task's schema by
    # to_train_cfg. Any, not BaseEnvCfg: a task's keys must merge into it before its type is known
    env: Any = field(default_factory=dict)
    policy: PolicyCfg = field(default_factory=PolicyCfg)
    algo: AlgoCfg = field(default_factory=AlgoCfg)
    runner: RunnerCfg = field(default_factory=RunnerCfg)

    BOUNDS = {"torch_threads": THREADS}

    def check_rules(self, p: str) -> None:
        # one rule for every seed: -1 or 2**64 would fail deep in numpy or torch (the first rule checked:
        # env.seed follows seed)
        check_seed_key("seed", self.seed)


def register_configs() -> None:
    """`train_schema` (the base of cfg/config.yaml) and one option of the group `env` per task."""
    store = ConfigStore.instance()
    store.store(name="train_schema", node=TrainCfg)
    for task in TASKS:
        store.store(group="env", name=task, node=env_schema(task))


def validate_train_cfg(cfg: TrainCfg) -> None:
    if not is_dataclass(cfg.env):
        raise ConfigError(
            "env must be built with its task's schema (lasmp.config.train.to_train_cfg does it)"
        )
    schema = env_schema(cfg.task)
    if type(cfg.env) is not schema:
        raise ConfigError(
            f"env is a {type(cfg.env).__name__} but task={cfg.task} needs a {schema.__name__}: the task picks "
            f"its env (task=rough_static selects env=rough_static); drop the env=<option> override"
        )
    # every key known (a `+key=value` typo, which Hydra appends, or a misspelt attribute set in code),
    # every number finite (NaN passes a range check written as a comparison), every section's limits and rules
    check_config(cfg, "")
    check_policy_fits_task(cfg)
    a, r = cfg.algo, cfg.runner
    if a.symmetry_cfg.enabled and not supports_mirror(registry.env_class(cfg.task)):
        raise ConfigError(f"algo.symmetry_cfg: task={cfg.task} has no mirror maps (moving_platform has)")
    samples = cfg.env.num_envs * r.num_steps_per_env  # each mini-batch holds at least one
    why = f"env.num_envs x runner.num_steps_per_env = {samples} samples"
    Bound(1, samples, why).check("algo.num_mini_batches", a.num_mini_batches, integer=True)
    if cfg.device != "cpu" and not cfg.device.startswith("cuda"):
        raise ConfigError(f"device must be cpu or cuda[:N], got {cfg.device!r}")


# the observation group an actor reads only when a policy key says so, and that key
GROUP_KEYS = {"alignment": "policy.use_alignment", "command": "policy.command_input"}


def check_policy_fits_task(cfg: TrainCfg) -> None:
    """Refuse a policy whose actor reads an observation group the task's env does not hand out (the
    moving platform's alignment command under task=rough_static), naming both: rsl_rl would fail
    later, building the actor, with a traceback."""
    given = registry.env_class(cfg.task).OBS_GROUPS
    missing = [g for g in actor_groups(cfg) if g not in given]
    if missing:
        keys = [GROUP_KEYS[g] for g in missing if g in GROUP_KEYS]
        raise ConfigError(
            f"policy={cfg.policy.name} does not fit task={cfg.task}: its actor reads the observation group(s) "
            f"{missing} ({', '.join(f'{k}=true' for k in keys)}), which the {cfg.task} env does not give (it gives "
            f"{list(given)}); pick a policy made for the task, or switch {' and '.join(keys)} off"
        )


def validate_logger(r: RunnerCfg) -> None:
    """An unknown runner.logger, or one whose package or credentials are missing, fails here, at start-up,
    not at the first iteration after the envs are built."""
    if r.logger not in LOGGERS:
        raise ConfigError(f"runner.logger must be one of {' | '.join(LOGGERS)}, got {r.logger!r}")
    if LOGGERS[r.logger] is None:
        return
    _, package, extra = LOGGERS[r.logger]
    project = getattr(r, f"{r.logger}_project")
    if not project:
        raise ConfigError(f"runner.{r.logger}_project must name a project for runner.logger={r.logger}")
    if not _installed(package):
        raise ConfigError(
            f"runner.logger={r.logger} needs the {package} package, which is not installed: "
            f'pip install -e ".[{extra}]"'
        )
    if r.logger == "neptune":  # rsl_rl's NeptuneLogWriter reads both
        missing = [v for v in ("NEPTUNE_API_TOKEN", "NEPTUNE_USERNAME") if not os.environ.get(v)]
        if missing:
            raise ConfigError(f"runner.logger=neptune needs {' and '.join(missing)} set in the environment")


def _installed(package: str) -> bool:
    return importlib.util.find_spec(package) is not None


def logger_cfg(r: RunnerCfg) -> str | dict[str, Any]:
    """rsl_rl's `logger` entry: "tensorboard", or the dict form of its W&B / Neptune writer."""
    spec = LOGGERS[r.logger]
    if spec is None:
        return r.logger
    return {"class_name": spec[0], "project_name": getattr(r, f"{r.logger}_project")}


def actor_groups(cfg: TrainCfg) -> list[str]:
    groups = ["policy", "history", "priv_explicit", "priv_implicit"]
    if cfg.policy.use_alignment:
        groups.append("alignment")
    if cfg.policy.command_input:
        groups.append("command")
    return groups


def rsl_rl_cfg(cfg: TrainCfg) -> dict[str, Any]:
    """The dict rsl_rl's OnPolicyRunner takes."""
    p, a, r = cfg.policy, cfg.algo, cfg.runner
    gaussian = {"class_name": "GaussianDistribution", "init_std": p.init_noise_std, "std_type": "scalar"}
    return {
        "num_steps_per_env": r.num_steps_per_env,
        "save_interval": r.save_interval,
        "check_for_nan": r.check_for_nan,
        "logger": logger_cfg(r),
        "obs_groups": {"actor": actor_groups(cfg), "critic": ["critic"]},
        "actor": {
            "class_name": ACTOR_CLASS,
            "hidden_dims": list(p.actor_hidden_dims),
            "activation": p.activation,
            "obs_normalization": True,
            "distribution_cfg": gaussian,
            "latent_dim": p.latent_dim,
            "encoder_hidden_dims": list(p.encoder_hidden_dims),
            "estimator_mlp_dim": p.estimator_mlp_dim,
            "estimator_channels": p.estimator_channels,
            "use_alignment": p.use_alignment,
            "explicit": p.explicit,
            "history_input": p.history_input,
            "command_input": p.command_input,
        },
        "critic": {
            "class_name": CRITIC_CLASS,
            "hidden_dims": list(p.critic_hidden_dims),
            "activation": p.activation,
            "obs_normalization": True,
        },
        "algorithm": {"class_name": ALGORITHM_CLASS, **OmegaConf.to_container(OmegaConf.structured(a))},
        "multi_gpu": None,
    }


def validates(task: str, validation_interval: int) -> bool:
    """Whether a training validates as it goes: the validation benchmark is the moving platform's."""
    return validation_interval > 0 and task == "moving_platform"


def to_plain(cfg: TrainCfg) -> dict:
    return OmegaConf.to_container(OmegaConf.structured(cfg))


def to_train_cfg(cfg) -> TrainCfg:
    """An OmegaConf/Hydra config (or a TrainCfg) as a validated TrainCfg, its env built with the
    task's schema and env.seed = seed."""
    if not isinstance(cfg, TrainCfg):
        cfg = OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(TrainCfg), cfg))
    if not is_dataclass(cfg.env):
        cfg.env = merge_env_cfg(dict(cfg.env or {}), schema=env_schema(cfg.task))  # validated below
    cfg.env.seed = cfg.seed
    validate_train_cfg(cfg)
    return cfg
