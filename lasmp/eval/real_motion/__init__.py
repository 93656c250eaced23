"""Real-motion test suite: physically modelled platform motions (ship, bus, train, lift, aircraft).

`motion` (the Motion type, deck-point kinematics, file conversion), one module per generator,
`suite` (the named scenarios, episodes and results). CLI: ``python -m lasmp.eval.real_motion --help``;
evaluation: ``python evaluate.py --suite real_motion ...``.
"""
