"""The one place lasmp reads private names of the libraries it builds on: rsl_rl (`rsl_rl`),
TensorBoard (`tensorboard`) and Hydra (`hydra`); tests fail here when a library renames them."""
