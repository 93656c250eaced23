"""`python -m lasmp.algo.checkpoint ...` (lasmp/algo/checkpoint/cli.py)."""

from lasmp.algo.checkpoint.cli import main

raise SystemExit(main())
