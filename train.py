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

from lasmp.cli.command_line import Sweep, unknown_key_error  # noqa: E402
from lasmp.config.train import register_configs  # noqa: E402

CONFIG_PATH, CONFIG_NAME = "cfg", "config"

register_configs()


SWEEP: Sweep | None = None  # with -m: the sweep's jobs and how each ended (lasmp/cli/command_line.py)


@hydra.main(version_base="1.3", config_path=CONFIG_PATH, config_name=CONFIG_NAME)
def main(cfg) -> None:
    from lasmp.cli.train import main as train_main

    if SWEEP is not None:  # a failed job is said, and the sweep goes on (docs/usage.md)
        SWEEP.run_job(lambda: train_main(cfg))
        return
    code = train_main(cfg)
    if code:
        raise SystemExit(code)


if __name__ == "__main__":
    error = unknown_key_error(sys.argv[1:], Path(__file__).resolve().parent / CONFIG_PATH, CONFIG_NAME)
    if error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    SWEEP = Sweep.of(sys.argv[1:])
    main()
    if SWEEP is not None:
        sys.exit(SWEEP.report())
