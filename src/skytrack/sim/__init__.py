"""skytrack.sim"""
