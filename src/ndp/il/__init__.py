"""ndp.il"""
