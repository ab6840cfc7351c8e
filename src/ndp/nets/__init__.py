"""ndp.nets"""
