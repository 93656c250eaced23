"""Rendering of a played env: the visual-only world (`world`), offscreen frames with a caption
(`renderer`, `caption`) and the interactive viewer (`viewer`). Used by `lasmp.cli.play`; the physics
model of training and evaluation is never changed by it."""
