"""ndp.dmp"""
