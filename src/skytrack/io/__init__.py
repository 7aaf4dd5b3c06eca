"""skytrack.io"""
