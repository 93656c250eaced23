"""Evaluation (docs/method.md, Evaluation): the fixed benchmark set Xi_eval (:mod:`lasmp.eval.benchmark`)."""
