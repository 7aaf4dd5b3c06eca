"""Identification of state estimates from two observation systems (spec 001; docs/methods/track-identification.md).

Two systems — a radar and ADS-B, two radars, a radar and an IFF interrogator — report
estimates of object states at their own instants; this package decides which belong to one
object.  Equations are the paper's (spec 001 §3), gaps its G1-G12:

* :mod:`.model` — the linear-Gaussian motion model in the paper's position-first order, (1), (2)
  and R1 (any model of :mod:`skytrack.models`; separate F_1, F_0 allowed);
* :mod:`.kalman` — the batched Kalman filters of (12)-(20) with Joseph updates (R2) and the exact
  diffuse start of R3 (gap G3; "smoothed" means filtered, G4; Q in the prediction, G5; per-report
  H, G6);
* :mod:`.sequential` — the optimal sequential test (3)-(20a): the joint filter over the merged
  stream and one filter per system, the four quadratic forms and Λ with its dof (R4; G2, G12),
  the Neyman–Pearson decision (R5; G7), the posterior with the log-determinants (R6; G1 — the
  literal ``include_logdet=False`` is miscalibrated and warns), the joint-only statistic (R15,
  G11);
* :mod:`.single_shot` — (20b)-(25): the single-shot test, the fused estimate (24) and the
  track-state test (R7, R8; ``half_statistic`` is the literal threshold on l/2, G8;
  ``track_states_test`` ignores the cross-correlation of common process noise);
* :mod:`.threshold` — R5's threshold modes (a fixed ``h=`` ignores the dof and drifts with the
  report geometry); :mod:`.potential`, :mod:`.design` — the potential characteristics (26)-(28b)
  and their NP design (R9, R10; gaps G9, G10: ``circular`` is the literal distance law, exact only
  for circular scattering);
* :mod:`.identifier`, :mod:`.pairing`, :mod:`.kernels`, :mod:`.assignment` — many-to-many
  identification (R13): tracks' filters shared by their pairs, pairs from a coarse gate, one
  compiled report loop per batch (R17), global assignment with a "no match" option, fusion of
  identified pairs (R14; ``fusion="information"`` is literal (24) on track states and
  over-confident with process noise).

Every module is batched over a leading axis of pairs, tracks or Monte Carlo trials.
"""

from skytrack.identify.identifier import IdentifierConfig, Identification, TrackIdentifier
from skytrack.identify.model import IdentificationModel, cv_model
from skytrack.identify.sequential import DIFFERENT, INSUFFICIENT, SAME, SequentialPairTest
from skytrack.identify.single_shot import fuse_information, single_shot, track_states_test
from skytrack.identify.threshold import Threshold

__all__ = [
    "DIFFERENT",
    "INSUFFICIENT",
    "SAME",
    "IdentificationModel",
    "Identification",
    "IdentifierConfig",
    "SequentialPairTest",
    "Threshold",
    "TrackIdentifier",
    "cv_model",
    "fuse_information",
    "single_shot",
    "track_states_test",
]
