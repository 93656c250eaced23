"""One rank of a tiny data-parallel training, run by tests/algo/test_distributed.py under torchrun.

    python -m torch.distributed.run --standalone --nproc_per_node=2 tests/algo/dist_worker.py CFG_JSON OUT_DIR

Trains with the JSON config (merged into the TrainCfg defaults), then every rank writes what the
test compares: its actor's and critic's parameters (normalizers included), its curriculum state
and the files it found in the log directory, to OUT_DIR/rank<k>.pt."""

import json
import os
import sys
from pathlib import Path

import torch
from omegaconf import OmegaConf

from lasmp.cli.train import train
from lasmp.config.train import to_train_cfg


def main() -> None:
    cfg = to_train_cfg(OmegaConf.create(json.loads(sys.argv[1])))
    out = Path(sys.argv[2])
    runner = train(cfg)
    rank = int(os.environ["RANK"])
    curriculum = runner.env.curriculum
    torch.save(
        {
            "actor": runner.alg.actor.state_dict(),
            "critic": runner.alg.critic.state_dict(),
            "estimators": runner.alg.estimator_optimizer.state_dict()["state"],
            "curriculum": curriculum.state_dict() if curriculum is not None else None,
            "iteration": runner.current_learning_iteration,
            "seed": runner.env.cfg.seed,
        },
        out / f"rank{rank}.pt",
    )


if __name__ == "__main__":
    main()
