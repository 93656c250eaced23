"""The command-line layer: what `train.py` and `play.py` run (`train`, `play`), the command line read
once (`command_line`), the one error boundary (`errors`), the resume and warm-start policies and the
checks made before a training builds anything (`preflight`, `resources`)."""
