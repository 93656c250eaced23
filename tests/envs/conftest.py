"""Shared set-up of the env tests."""

from __future__ import annotations

import numpy as np
import pytest

from lasmp.envs import trajectories as T


@pytest.fixture(scope="module")
def traj():
    """300 approximating trajectories of the testing split (seed 123): test_trajectory_splines.py's
    and test_trajectory_files.py's set."""
    return T.sample(300, T.TEST_RANGES, np.random.default_rng(123))
