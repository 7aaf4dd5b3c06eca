"""skytrack.cli"""
