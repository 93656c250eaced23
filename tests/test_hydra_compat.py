"""What lasmp takes from Hydra's internals (lasmp/compat/hydra.py says why) is still there and still
reads a command line and expands a sweep as lasmp expects: an upgrade that moves one fails here."""

from __future__ import annotations

import pytest
from hydra.errors import HydraException

from lasmp.compat.hydra import args_parser, basic_sweep_jobs


def test_the_parser_reads_the_command_line_as_hydra_main_does():
    args = args_parser().parse_args(["-m", "seed=1,2", "env.num_envs=4"])
    assert args.multirun and args.overrides == ["seed=1,2", "env.num_envs=4"]
    assert (args.config_path, args.config_dir, args.config_name) == (None, None, None)
    args = args_parser().parse_args(["--config-name", "other", "seed=1"])
    assert not args.multirun and args.config_name == "other" and args.overrides == ["seed=1"]


def test_a_sweep_expands_into_its_jobs_in_the_basic_sweeper_s_order():
    assert basic_sweep_jobs(["a=1,2", "b=x,y", "c=3"]) == [
        ["a=1", "b=x", "c=3"],
        ["a=1", "b=y", "c=3"],
        ["a=2", "b=x", "c=3"],
        ["a=2", "b=y", "c=3"],
    ]
    assert basic_sweep_jobs(["seed=range(1,3)"]) == [["seed=1"], ["seed=2"]]
    assert basic_sweep_jobs(["seed=0"]) == [["seed=0"]]


def test_a_sweep_the_basic_sweeper_cannot_expand_raises():
    with pytest.raises(HydraException, match="(?i)interval"):
        basic_sweep_jobs(["lr=interval(0,1)"])
