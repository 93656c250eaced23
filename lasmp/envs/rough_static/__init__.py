"""The R-S baseline task: A1 locomotion on static rough terrain with pushes and velocity commands.

`lasmp.envs.rough_static.env.RoughStaticEnv` (config: `lasmp.envs.rough_static.cfg.RoughStaticCfg`),
registered in `lasmp.envs.registry`. Nothing is imported here: the cfg module must import without
the env (`lasmp.config.train` reads the schemas), and the env imports the cfg.
"""
