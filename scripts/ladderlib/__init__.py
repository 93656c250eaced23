"""scripts/ladder.py's report: its table and figure, from the collected runs' validation curves."""
