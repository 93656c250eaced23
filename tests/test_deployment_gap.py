"""bench/deployment_gap.py's input modes: the shuffled-estimates probe feeds each env another env's x_exp."""

import numpy as np
import pytest
from testkit import load_script

gap = load_script("bench/deployment_gap.py")


@pytest.mark.parametrize("n", [2, 3, 7, 1000])
def test_the_derangement_gives_every_env_another_envs_estimates(n):
    perm = gap.derangement(n, seed=n)
    assert sorted(perm.tolist()) == list(range(n))
    assert (perm != np.arange(n)).all()


def test_one_env_cannot_read_another_envs_estimates_and_is_refused_before_any_episode(capsys):
    with pytest.raises(ValueError, match="at least 2 envs"):
        gap.derangement(1)
    with pytest.raises(SystemExit):
        gap.main(["--checkpoint", "does-not-matter.pt", "--num-envs", "1", "--modes", "", "s"])
    assert "mode s" in capsys.readouterr().err
