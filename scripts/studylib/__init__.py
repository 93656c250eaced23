"""scripts/study.py's modules: the study's plan (plan), its runs (runs), its tables (tables)."""
