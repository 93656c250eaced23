"""6-DoF platform reference trajectories (docs/trajectories.md): generation, evaluation, files, statistics.

Pose
    Everywhere a pose is ``[x, y, z, roll, pitch, yaw]`` (m, m, m, rad, rad, rad): the platform's
    joint displacement from its initial pose, so the initial pose is all zeros. The rotational
    joints compose as ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``; nothing here rotates anything.

Constructions (:mod:`.splines`, with ``scipy.interpolate``)
    Generated sets (:func:`sample`, :mod:`.generate`): N waypoints drawn uniformly in a split's
    ranges over T become, by :class:`SplineSpec`, either the control points of a clamped uniform
    B-spline of degree 10 with tripled ends (``"approximating"``, the default: it starts at the
    initial pose and ends at w_N with zero velocity and acceleration) or the knots of a clamped
    cubic through them (``"interpolating"``). User-made sets (:func:`from_samples`,
    :mod:`.user_made`): a not-a-knot cubic through sampled poses. Every set, whatever its
    construction, is a :class:`PiecewisePoly`, evaluated for thousands of rows in one Horner pass.

Files (:mod:`.fileformat`)
    ``.npz``, format "lasmp-trajectories" version 2, written by :func:`save`, read by
    :func:`load`: generated sets as their waypoints and construction, user-made sets as their
    samples. A malformed file or user-made trajectory raises :class:`TrajectoryFileError`.
    Every ``.npz`` reader (:func:`read_npz`, the benchmark file's too) checks each member's size
    from its header before loading it (:func:`check_npz_members`, at most ``MAX_NPZ_BYTES``).

Statistics (:mod:`.stats`)
    :func:`statistics`: path length, speed, acceleration, angular rate and curvature, per N.

CLI (:mod:`.cli`): ``python -m lasmp.envs.trajectories {stats,plot,generate} --help``.

Everything public is importable from here: ``from lasmp.envs import trajectories as trj``.
"""

from lasmp.envs.trajectories.cli import main
from lasmp.envs.trajectories.fileformat import (
    FORMAT_NAME,
    FORMAT_VERSION,
    MAX_NPZ_BYTES,
    check_npz_members,
    check_version,
    load,
    read_npz,
    save,
    waypoint_arrays,
    waypoints_from_arrays,
)
from lasmp.envs.trajectories.generate import (
    TEST_RANGES,
    TRAIN_RANGES,
    TrajectoryRanges,
    ranges_for_split,
    sample,
)
from lasmp.envs.trajectories.splines import (
    APPROXIMATING,
    DEFAULT_DEGREE,
    END_REPEATS,
    GENERATED_KINDS,
    INTERPOLATING,
    KIND_NAMES,
    MAX_DEGREE,
    POSE_NAMES,
    SAMPLES,
    PiecewisePoly,
    SplineSpec,
)
from lasmp.envs.trajectories.stats import STAT_COLUMNS, angular_rate, print_table, statistics
from lasmp.envs.trajectories.user_made import TrajectoryFileError, from_samples

__all__ = [
    "APPROXIMATING",
    "DEFAULT_DEGREE",
    "END_REPEATS",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "GENERATED_KINDS",
    "INTERPOLATING",
    "KIND_NAMES",
    "MAX_DEGREE",
    "MAX_NPZ_BYTES",
    "POSE_NAMES",
    "SAMPLES",
    "STAT_COLUMNS",
    "TEST_RANGES",
    "TRAIN_RANGES",
    "PiecewisePoly",
    "SplineSpec",
    "TrajectoryFileError",
    "TrajectoryRanges",
    "angular_rate",
    "check_npz_members",
    "check_version",
    "from_samples",
    "load",
    "main",
    "print_table",
    "ranges_for_split",
    "read_npz",
    "sample",
    "save",
    "statistics",
    "waypoint_arrays",
    "waypoints_from_arrays",
]
