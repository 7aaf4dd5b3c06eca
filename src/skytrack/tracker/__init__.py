"""skytrack.tracker"""
