"""bench/config_walk.py: the counts of a walk (stays, rooms, climbs back) on a constructed sequence of
rooms, its overrides on top of the tiny sizes, and one walk of the tiny training, run as a user runs it."""

from __future__ import annotations

import json

from testkit import TINY_CLI, load_script, run_script

walk = load_script("bench/config_walk.py")


def test_a_stay_is_a_run_of_calls_in_one_room_and_a_climb_back_a_stay_in_a_room_left_before():
    rooms = ["a", "a", "b", "a", "c", "c", "b", "b"]
    # stays: a(2) b(1) a(1) c(2) b(2): the second a and the second b are re-entries
    assert walk.count_walk(rooms) == {"calls": 8, "stays": 5, "rooms": 3, "climbs_back": 2}
    stays = walk.stays_of([(room, f"f{i}") for i, room in enumerate(rooms)])
    assert [(s["room"], s["function"], s["calls"], s["climb_back"]) for s in stays] == [
        ("a", "f0", 2, False),
        ("b", "f2", 1, False),
        ("a", "f3", 1, True),
        ("c", "f4", 2, False),
        ("b", "f6", 2, True),
    ]


def test_an_empty_walk_and_a_walk_in_one_room_have_no_climb_back():
    assert walk.count_walk([]) == {"calls": 0, "stays": 0, "rooms": 0, "climbs_back": 0}
    assert walk.count_walk(["a"] * 3) == {"calls": 3, "stays": 1, "rooms": 1, "climbs_back": 0}


def test_the_walk_runs_the_tests_tiny_training_and_an_override_replaces_its_key():
    assert walk.TINY_CLI == TINY_CLI
    composed = walk.walk_overrides(["env.num_envs=8", "runner.log_dir=elsewhere"], "/tmp/x")
    assert "env.num_envs=8" in composed and "env.num_envs=4" not in composed
    assert "runner.max_iterations=1" in composed and "seed=0" in composed
    assert [o for o in composed if o.startswith("runner.log_dir=")] == ["runner.log_dir=/tmp/x"]


def test_the_tiny_training_walks_its_config_from_main_through_the_config_module(tmp_path):
    done = run_script("bench/config_walk.py", "--json", cwd=tmp_path)
    report = json.loads(done.stdout)
    rooms = {s["room"] for s in report["stays_sequence"]}
    assert {"lasmp/cli/train.py", "lasmp/config/train.py"} <= rooms
    assert report["stays_sequence"][0]["room"] == "lasmp/cli/train.py"
    assert report["stays_sequence"][0]["function"] == "main"
    assert report["stays"] > 0 and report["rooms"] == len(rooms)
    assert report["climbs_back"] == report["stays"] - report["rooms"]
    assert report["reached_learn"]  # followed up to LasmpRunner.learn, where the walk is cut


def test_the_config_reaches_the_start_of_learning_in_at_most_20_stays_and_5_climbs_back(tmp_path):
    """The house's goal for a training's way through the code (docs/layout.md): the config's own
    classes followed from `main` to `LasmpRunner.learn` at the tiny sizes."""
    done = run_script("bench/config_walk.py", "--config-classes", "--json", cwd=tmp_path)
    report = json.loads(done.stdout)
    assert report["reached_learn"]
    way = " -> ".join(s["room"] for s in report["stays_sequence"])
    assert report["stays"] <= 20 and report["climbs_back"] <= 5, way
