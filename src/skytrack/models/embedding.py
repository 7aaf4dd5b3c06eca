"""Embedding of motion models in a state of m = 3 states per axis (spec 004 §2, §3.3 B, R1).

The multiple-model filters of spec 004 (model bank, IMM, VD) hold every model in the layout
``[x, vx, ax, y, vy, ay, z, vz, az]``.  A model of lower order is embedded by padding: its F
and Q fill the leading block of each axis and the added rows and columns are zero, e.g. CV:
``F_cv = [[1, T, 0], [0, 1, 0], [0, 0, 0]]``, DWNA ``g = [T^2/2, T, 0]``.  The acceleration of
an embedded CV model is therefore reset to zero at every prediction (and its F is singular:
backward extrapolation through its Moore-Penrose inverse keeps the acceleration at zero, and
``F(0) = diag(1, 1, 0)``, not the identity).

:func:`embed` maps a :class:`~skytrack.models.motion.MotionModel` axis by axis
(:class:`EmbeddedAxis`), returns models that already have the order unchanged (CA, Singer,
DWPA), and turns a :class:`~skytrack.models.turn.CoordinatedTurn` into its order-3 layout
(``ct_acceleration`` chosen there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.models.motion import AxisModel, MotionModel
from skytrack.models.turn import CoordinatedTurn


@dataclass(frozen=True)
class EmbeddedAxis(AxisModel):
    """Axis model ``base`` padded with zero rows/columns to ``order`` states per axis."""

    base: AxisModel
    order: int = 3

    def __post_init__(self):
        if not isinstance(self.base, AxisModel):
            raise ValueError(f"embedded axis: base must be an AxisModel, got {type(self.base).__name__}")
        if not (isinstance(self.order, (int, np.integer)) and self.order >= self.base.order):
            raise ValueError(f"embedded axis: order must be an integer >= the base order {self.base.order}, "
                             f"got {self.order!r}")

    def _pad(self, M: np.ndarray) -> np.ndarray:
        k = self.base.order
        out = np.zeros(M.shape[:-2] + (self.order, self.order))
        out[..., :k, :k] = M
        return out

    def F_batch(self, dt) -> np.ndarray:
        return self._pad(self.base.F_batch(dt))

    def Q_batch(self, dt) -> np.ndarray:
        return self._pad(self.base.Q_batch(dt))


def embed(model, order: int = 3):
    """``model`` in the layout of ``order`` states per axis (spec 004: multiple-model filters use 3).

    MotionModel axes of lower order become :class:`EmbeddedAxis`; axes of order ``order`` are kept;
    a :class:`CoordinatedTurn` returns ``model.embedded(order)``.  A higher order than ``order``
    is a ValueError.
    """
    if isinstance(model, CoordinatedTurn):
        if order not in (2, 3):
            raise ValueError(f"embed: a coordinated turn has order 2 or 3, got order={order!r}")
        if model.order > order:
            raise ValueError(f"embed: cannot embed an order-{model.order} model in order {order}")
        return model.embedded(order)
    if not isinstance(model, MotionModel):
        raise ValueError(f"embed: model must be a MotionModel or CoordinatedTurn, got {type(model).__name__}")
    if model.order > order:
        raise ValueError(f"embed: cannot embed an order-{model.order} model in order {order}")
    if model.order == order:
        return model
    return MotionModel([EmbeddedAxis(axis, order) for axis in model.axes])
