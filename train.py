"""Train a LAS-MP policy: `python train.py task=moving_platform [policy=...] [key=value ...]`.

See cfg/config.yaml for the groups and lasmp/train_cfg.py for every key.
"""

import hydra

from lasmp.train_cfg import register_configs

register_configs()


@hydra.main(version_base="1.3", config_path="cfg", config_name="config")
def main(cfg) -> None:
    import sys

    from lasmp.algo.checkpoint import CheckpointError
    from lasmp.algo.runner import TrainingInterrupted
    from lasmp.config import ConfigError
    from lasmp.train import train

    try:
        train(cfg)
    except TrainingInterrupted as stop:  # checkpoint written and resume command printed
        raise SystemExit(128 + stop.signum) from None
    except (CheckpointError, ConfigError) as err:  # bad input: one line, no traceback
        print(f"error: {err}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
