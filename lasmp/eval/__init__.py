"""Evaluation (SPEC §12): the fixed benchmark set Xi_eval (:mod:`lasmp.eval.benchmark`)."""
