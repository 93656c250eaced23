"""Friction is isotropic (docs/world.md, The robot): with the default contact settings a block and the standing A1
hold on a tilted platform below atan(mu) and slide above it whichever way the slope faces, and
MuJoCo's pyramidal cone, which does not, fails the same check.

A coarse, fixed-tilt form of bench/friction_cone.py's protocol (its world and helpers, from
bench/slide_protocol.py): settle on the level platform, tilt to a fixed angle in 2 s, hold 2 s. A run
"holds" when no tracked point (the block's body, the robot's four feet) slips 2 mm along the surface
in the hold's last second (the block: nor 1 cm over the whole hold), and "slides" when every one
slips more than 5 cm over the hold.
"""

from __future__ import annotations

import math

import pytest
from testkit import load_script

from lasmp.config.base import SimCfg

fc = load_script("bench/slide_protocol.py")

BLOCK_MU = 0.5
ROBOT_MU = 0.3  # low enough that the robot slides (16.7 deg) before it tips over sideways (~23 deg)
PYRAMIDAL = SimCfg(cone="pyramidal", impratio=1.0, noslip_iterations=0)


def _tilt_deg(mu: float, factor: float) -> float:
    return factor * math.degrees(math.atan(mu))


def _holds(run: dict, block: bool) -> bool:
    stopped = bool((run["last_s_slip_m"] < 0.002).all())
    return stopped and (not block or bool((run["slip_m"] < 0.01).all()))


def _slides(run: dict) -> bool:
    return bool((run["slip_m"] > 0.05).all())


@pytest.mark.parametrize("azimuth_deg", [0.0, 45.0, 90.0])
def test_a_block_on_the_default_contacts_holds_just_below_atan_mu_and_slides_just_above_whichever_way_the_slope_faces(
    azimuth_deg,
):
    sim = SimCfg()
    below = fc.fixed_tilt_slip(sim, "block", BLOCK_MU, azimuth_deg, _tilt_deg(BLOCK_MU, 0.95))
    above = fc.fixed_tilt_slip(sim, "block", BLOCK_MU, azimuth_deg, _tilt_deg(BLOCK_MU, 1.05))
    assert _holds(below, block=True), (
        f"slipped {below['slip_m']} m at 0.95 atan(mu), downhill {azimuth_deg} deg"
    )
    assert _slides(above), f"slipped only {above['slip_m']} m at 1.05 atan(mu), downhill {azimuth_deg} deg"


@pytest.mark.parametrize(
    "azimuth_deg, hold_factor",
    [
        # facing down the slope the stance's own leg forces take part of the feet's friction (every
        # foot is on the cone's boundary, but partly sideways): from ~0.85 atan(mu) the feet slip
        # 1-7 cm and re-stick, and the whole robot slides from ~0.93 atan(mu) (bench/friction_cone.py)
        (0.0, 0.9),
        (45.0, 0.95),
    ],
    ids=["forward", "diagonal"],
)
def test_the_standing_robot_on_the_default_contacts_holds_below_atan_mu_and_slides_just_above_forward_and_diagonally(
    azimuth_deg, hold_factor
):
    sim = SimCfg()
    below = fc.fixed_tilt_slip(sim, "robot", ROBOT_MU, azimuth_deg, _tilt_deg(ROBOT_MU, hold_factor))
    above = fc.fixed_tilt_slip(sim, "robot", ROBOT_MU, azimuth_deg, _tilt_deg(ROBOT_MU, 1.05))
    assert _holds(below, block=False), (
        f"feet still slipping {below['last_s_slip_m']} m/s at {hold_factor} atan(mu)"
    )
    assert _slides(above), f"feet slipped only {above['slip_m']} m at 1.05 atan(mu)"


def test_the_pyramidal_cone_lets_a_block_and_the_robot_slide_diagonally_well_below_atan_mu_where_along_an_axis_it_only_creeps():
    axis = fc.fixed_tilt_slip(PYRAMIDAL, "block", BLOCK_MU, 0.0, _tilt_deg(BLOCK_MU, 0.85))
    diagonal = fc.fixed_tilt_slip(PYRAMIDAL, "block", BLOCK_MU, 45.0, _tilt_deg(BLOCK_MU, 0.85))
    robot = fc.fixed_tilt_slip(PYRAMIDAL, "robot", ROBOT_MU, 45.0, _tilt_deg(ROBOT_MU, 0.95))
    # along an axis the block only creeps (this cone's soft contacts have no no-slip pass)
    assert (axis["slip_m"] < 0.01).all(), (
        f"the block slipped {axis['slip_m']} m along an axis at 0.85 atan(mu)"
    )
    assert _slides(diagonal), f"the block slipped only {diagonal['slip_m']} m diagonally at 0.85 atan(mu)"
    assert _slides(robot), f"the robot's feet slipped only {robot['slip_m']} m diagonally at 0.95 atan(mu)"
