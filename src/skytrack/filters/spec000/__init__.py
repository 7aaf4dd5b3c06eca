"""Singer-model track filters with missed detections: the spec 000 paper filters.

One module per idea; the public names are re-exported here and from :mod:`skytrack.filters`.

* :mod:`.params` — :class:`SingerParams` (per-step coefficients sigma_a, tau) and
  :class:`SingerHistory`, what a non-anticipative coefficient policy sees (R10, (2a)).
* :mod:`.switching` — :class:`ManeuverSwitch`, the manoeuvre indicator psi of (S3).
* :mod:`.kernels` — batch-last Theorem 2 (5) prediction and Theorem 1 (3)-(4) covariance
  update kernels, F and Q of (K6) / (X1)-(X2), small Cholesky factors (private).
* :mod:`.validation` — measurement variants (M2)/(M3) and argument checks (R16).
* :mod:`.steady_state` — :func:`steady_state`, the P_D = 1 limits (P-, P+) from the discrete
  algebraic Riccati equation (R12, TV8; the paper's A1).
* :mod:`.covariance` — :func:`covariance_recursion`, the covariance half of the filter along
  realised detection patterns (the paper's accuracy protocol A1-A3, §6).
* :mod:`.bank1d` — :class:`SingerFilterBank1D`, N independent one-axis Singer filters (state
  ``(x, v, a)``, position or position + velocity measurement) advanced together, the batched
  form used by the accuracy study (E1-E6), the Monte Carlo consistency check (R14) and the
  long-run hygiene check (R16).
* :mod:`.filter1d` — :class:`SingerFilter1D`, the paper's 1-D filter (R3, R4, R6, R7, R13,
  R16) for one track, a bank of size one plus the switching-coefficient interface (R10).
* :mod:`.tracker3d` — :class:`SingerTracker3D`, the 3-D polar-radar EKF of R8/R9 with the
  Singer model per ENU axis, built on the batched EKF core :mod:`skytrack.filters.ekf`.

Equations.  One scan is Theorem 2 (5) followed by Theorem 1 (3)-(4) written in Kalman
form (spec 000 §3.1 "Check"): with F, Q from (K6) (``"paper"``) or (X1)-(X2) (``"exact"``)

    em = F m,  eP = F P F^T + Q                                     (Theorem 2, eq. 5)
    S = H eP H^T + R,  K = eP H^T S^-1,  m+ = em + K (z - H em)       (eq. 3 / F1-F6)
    P+ = (I - K H) eP (I - K H)^T + K R K^T   ("joseph", default)
    P+ = eP - K S K^T                          ("standard", the literal form of eq. 4)

both followed by P <- (P + P^T)/2.  For the paper model this is (F1)-(F10).  A missed scan
(phi(p_n) = 0, R4, S1) is the prediction alone: the covariance follows the realised flag
sequence and no P_D enters it; the fictitious p_n of (M5)-(M8) has dropped out.

Layout.  The public arrays are batch-first (``m[N, 3]``, ``P[N, 3, 3]``, DESIGN.md rule 1).
The 1-D kernels work internally on batch-last copies (``m[3, N]``, ``P[3, 3, N]``)
because numpy's stacked matmul is an order of magnitude slower than element-wise
arithmetic over a trailing batch axis for 3x3 matrices (measured: 2.1 ms against 0.23 ms
for 20 000 products), and the study needs 10^7-10^8 track-scans.
"""

from skytrack.filters.spec000.bank1d import BankStepResult, SingerFilterBank1D
from skytrack.filters.spec000.covariance import CovarianceAverages, covariance_recursion
from skytrack.filters.spec000.filter1d import SingerFilter1D, StepResult
from skytrack.filters.spec000.params import SingerHistory, SingerParams
from skytrack.filters.spec000.steady_state import SteadyState, steady_state
from skytrack.filters.spec000.switching import ManeuverSwitch
from skytrack.filters.spec000.tracker3d import (
    CARTESIAN_COMPONENTS,
    MIN_RANGE_M,
    REPORT_COMPONENTS,
    Innovation3D,
    SingerTracker3D,
)
from skytrack.filters.spec000.validation import MEASUREMENT_INDEX

__all__ = [
    "BankStepResult",
    "CARTESIAN_COMPONENTS",
    "CovarianceAverages",
    "Innovation3D",
    "MEASUREMENT_INDEX",
    "MIN_RANGE_M",
    "ManeuverSwitch",
    "REPORT_COMPONENTS",
    "SingerFilter1D",
    "SingerFilterBank1D",
    "SingerHistory",
    "SingerParams",
    "SingerTracker3D",
    "SteadyState",
    "StepResult",
    "covariance_recursion",
    "steady_state",
]
