"""Train a LAS-MP policy: `python train.py task=moving_platform [policy=...] [key=value ...]`.

See cfg/config.yaml for the groups and lasmp/train_cfg.py for every key.
"""

import hydra

from lasmp.train_cfg import register_configs

register_configs()


@hydra.main(version_base="1.3", config_path="cfg", config_name="config")
def main(cfg) -> None:
    from lasmp.algo.runner import TrainingInterrupted
    from lasmp.train import train

    try:
        train(cfg)
    except TrainingInterrupted as stop:  # checkpoint written and resume command printed
        raise SystemExit(128 + stop.signum) from None


if __name__ == "__main__":
    main()
