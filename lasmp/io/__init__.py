"""Run directories and safe files: the commands' one error boundary (`errors`), atomic writes
(`atomic`), a run directory's lock and checkpoints (`rundir`), checked inputs (`inputs`), running state
as plain data (`plainstate`), the memory a process may allocate (`memory`) and a quiet Ctrl-C while
loading (`ctrl_c`)."""
