"""The R-S baseline task: A1 locomotion on static rough terrain with pushes and velocity commands.

`lasmp.envs.rough_static.env.RoughStaticEnv` (config: `lasmp.config.RoughStaticCfg`). Nothing
is imported here: `lasmp.config` imports this package's `rewards`, and the env imports the config.
"""
