"""ndp.policies"""
