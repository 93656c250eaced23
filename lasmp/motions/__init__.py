"""Physical motion models of real vehicles, as platform trajectory sources.

Each generator returns a :class:`lasmp.motions.motion.Motion`: the pose of the 2 x 2 m patch of
floor a robot stands on, sampled at 100 Hz, in the trajectory convention of
:mod:`lasmp.envs.trajectories` (and written as a "samples" trajectory file by
:func:`lasmp.motions.motion.to_trajectories`).

Sources: :mod:`.ship` (a deck in a JONSWAP sea), :mod:`.bus` (a city bus floor), :mod:`.rail`
(a passenger coach on a canted curve and irregular track), :mod:`.lift` (a lift car),
:mod:`.aircraft` (a cabin floor in Dryden turbulence). Shared pieces: :mod:`.motion` (the type,
deck-point kinematics, checks), :mod:`.noise` (coloured noise, filters), :mod:`.profiles`
(jerk-limited speed profiles). The models, their parameter values and their sources:
docs/real_motion.md. The scenario suite built on them lives in :mod:`lasmp.eval.real_motion`.
"""
