"""Lowest layer: batched linear algebra, typed plot batches and the track-table columns.

Nothing here imports another skytrack package.
"""
