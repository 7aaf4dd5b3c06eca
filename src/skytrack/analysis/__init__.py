"""skytrack.analysis"""
