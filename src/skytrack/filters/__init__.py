"""Estimators over batches of tracks: the batched (E)KF core and spec-000 Singer filters."""

from skytrack.filters.ekf import (
    UPDATE_FORMS,
    UpdateResult,
    innovation,
    innovation_covariance,
    mahalanobis,
    predict,
    symmetrize,
    update,
)

__all__ = [
    "UPDATE_FORMS",
    "UpdateResult",
    "innovation",
    "innovation_covariance",
    "mahalanobis",
    "predict",
    "symmetrize",
    "update",
]
