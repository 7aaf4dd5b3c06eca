"""Identification of state estimates from two observation systems (spec 001).

Being built (issue 9): potential characteristics, the sequential pair test, the
single-shot test, many-to-many identification and fusion.
"""
