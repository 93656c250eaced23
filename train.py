"""Train a LAS-MP policy: `python train.py task=moving_platform [policy=...] [key=value ...]`.

See cfg/config.yaml for the groups and lasmp/config/train.py for every key; lasmp/cli/train.py for the run
(build, resume, learn) and lasmp/cli/resume.py for what a resume keeps, takes and refuses.
"""

import sys
from pathlib import Path

from lasmp.io.ctrl_c import quiet_ctrl_c

quiet_ctrl_c()  # before torch and Hydra load: a Ctrl-C then says one line

from lasmp.cli.preflight import exit_unless_mujoco_imports  # noqa: E402

exit_unless_mujoco_imports()  # a bad MUJOCO_GL: one line, not the traceback of the first import below

import hydra  # noqa: E402

from lasmp.cli.command_line import hydra_overrides, run  # noqa: E402
from lasmp.config.train import register_configs  # noqa: E402

CONFIG_PATH, CONFIG_NAME = "cfg", "config"

register_configs()


def job(cfg, overrides: list[str]) -> int:
    from lasmp.cli.train import main as train_main

    return train_main(cfg, overrides)


@hydra.main(version_base="1.3", config_path=CONFIG_PATH, config_name=CONFIG_NAME)
def hydra_app(cfg) -> None:
    """Hydra's own app, for what lasmp leaves to it (`lasmp.cli.command_line.HYDRA_OWN`: --help,
    --info, another config; a sweep only its sweeper can expand)."""
    code = job(cfg, hydra_overrides())
    if code:
        raise SystemExit(code)


if __name__ == "__main__":
    config_dir = Path(__file__).resolve().parent / CONFIG_PATH
    sys.exit(run(sys.argv[1:], config_dir, CONFIG_NAME, job, hydra_app))
