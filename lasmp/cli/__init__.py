"""The command-line layer: what `train.py` and `play.py` run (`train`, `play`), train.py's command line
read once (`command_line`) and its sweeps (`sweep`), the resume and warm-start policies and the checks
made before a training builds anything (`preflight`, `resources`). The commands' one error boundary is
`lasmp.io.errors`, a layer below, so that evaluate.py (`lasmp.eval.cli`) shares it."""
