"""Train a LAS-MP policy: `python train.py task=moving_platform [policy=...] [key=value ...]`.

See cfg/config.yaml for the groups and lasmp/train_cfg.py for every key; lasmp/train.py for run
directories and resume.
"""

import hydra

from lasmp.train_cfg import register_configs

register_configs()


@hydra.main(version_base="1.3", config_path="cfg", config_name="config")
def main(cfg) -> None:
    from lasmp.train import main as train_main

    code = train_main(cfg)
    if code:
        raise SystemExit(code)


if __name__ == "__main__":
    main()
