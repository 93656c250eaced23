"""The real-motion suite: named vehicle scenarios played as a benchmark, their results and figures.

The motions themselves are trajectory sources in :mod:`lasmp.motions` (ship, bus, rail, lift,
aircraft); here are `suite` (the scenarios, episodes, platform drive and results tables) and
`plots`. CLI: ``python -m lasmp.eval.real_motion --help``; evaluation: ``python evaluate.py --suite
real_motion ...``. How to run it and what it measured: docs/real_motion.md.
"""
