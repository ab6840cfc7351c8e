"""ndp.rl"""
