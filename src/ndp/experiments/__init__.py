"""ndp.experiments"""
