"""skytrack.association"""
