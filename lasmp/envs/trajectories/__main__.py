"""``python -m lasmp.envs.trajectories {stats,plot,generate} --help`` (:mod:`lasmp.envs.trajectories.cli`)."""

import sys

from lasmp.envs.trajectories.cli import main

if __name__ == "__main__":
    sys.exit(main())
