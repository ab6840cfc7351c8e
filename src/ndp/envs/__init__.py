"""ndp.envs"""
