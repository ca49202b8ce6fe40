"""exobench.envs"""
