"""The frame of spec 003's paper (X north, Y east, Z up) and skytrack's ENU frame (R1, §2.2).

The paper writes positions and velocities in a ground-fixed frame OXYZ with X north,
Y east and Z up.  That frame is **left-handed** (north x east = down).  skytrack never
computes in it: every model and filter works in the right-handed local East-North-Up
frame (e, n, u) of DESIGN.md, and the paper's frame exists only to read or write the
paper's numbers.  The map between them swaps the first two axes,

    e = Y,  n = X,  u = Z;     v_e = V_y,  v_n = V_x,  v_u = V_z,

a reflection (determinant -1), not a rotation: a formula from literature written in the
paper's frame must be carried through this map, not converted by renaming axes in place.

Azimuth is the same physical angle in both frames, clockwise from north:
alpha = atan2(Y - Y_o, X - X_o) = atan2(e - e_o, n - n_o); elevation and range are the same too.

Arrays are ``[..., 3]`` (positions or velocities) or ``[..., 6]`` (position then velocity).
The swap is its own inverse, so both directions are one function.
"""

from __future__ import annotations

import numpy as np

#: column order that swaps the first two axes of a 3-vector and of a position-velocity 6-vector
_SWAP_ORDER = {3: np.array([1, 0, 2]), 6: np.array([1, 0, 2, 4, 3, 5])}


def _swap_north_east(values) -> np.ndarray:
    array = np.asarray(values, dtype=float)
    order = _SWAP_ORDER.get(array.shape[-1] if array.ndim else 0)
    if order is None:
        raise ValueError(f"expected an array [..., 3] or [..., 6], got shape {array.shape}")
    return array[..., order]


def paper_xyz_to_enu(xyz) -> np.ndarray:
    """Paper frame (X north, Y east, Z up[, V_x, V_y, V_z]) to ENU (e, n, u[, v_e, v_n, v_u])."""
    return _swap_north_east(xyz)


def enu_to_paper_xyz(enu) -> np.ndarray:
    """ENU (e, n, u[, v_e, v_n, v_u]) to the paper frame (X north, Y east, Z up[, V_x, V_y, V_z])."""
    return _swap_north_east(enu)
