"""IFF / secondary-radar responder of the simulator, with injected errors (spec 003 R18, R16).

:func:`respond` answers the interrogation of a batch of plots from their true objects:

* an interrogated plot of an object carries a reply with probability ``p_reply`` (scalar
  or one value per object); otherwise both its status and its code are missing;
* the replied status is the object's true one (friend 0 / foe 1, the codes of
  :data:`skytrack.core.plots.IFF_VALUES`), flipped friend <-> foe with probability
  ``p_flip``;
* the replied code (Mode 3/A as ``int(code, 8)``) is the object's true one, replaced with
  probability ``p_code`` by a code drawn uniformly from the other 4095 valid 4-digit octal
  codes;
* a plot of no object (``true_object == -1``, a false plot) carries no reply, unless
  ``false_reply_p`` > 0: then it replies with that probability with a status uniform over
  friend/foe and a code uniform over all 4096 codes (fruit, garbled replies);
* an object whose true status is -1 has no IFF transponder and never replies.

Random streams (R18, TV13 (c)): the draws are made for *every* plot, interrogated or not,
in one fixed order (one block of uniforms, then the replacement codes, then the false
replies), so that changing the request mask or any probability changes only which draws
are used, never the draws themselves nor any other random stream.  The caller gives the
responder a generator of its own (the simulator spawns one for IFF), so that turning IFF
on or off leaves the measurement noise, detection and plot order bit-identical.

:func:`interrogation_mask` is the simulator's interrogation policy: ``always``, ``never``
or time windows.  The tracker-driven policy ``track`` of R16 needs the tracker's predicted
tracks and is not a simulator policy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

FRIEND, FOE, UNDETERMINED = 0, 1, 2
NO_REPLY = -1
#: number of 4-digit octal (Mode 3/A) codes, 0000-7777
MODE3A_CODE_COUNT = 8**4
INTERROGATION_POLICIES = ("always", "never")


def _per_object(name: str, value, n_objects: int) -> np.ndarray:
    """A probability given as a scalar or one value per object, checked to lie in [0, 1]."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = np.full(n_objects, float(array))
    elif array.shape != (n_objects,):
        raise ValueError(f"{name} must be a scalar or have one value per object ({n_objects}), got shape {array.shape}")
    if not np.all((array >= 0.0) & (array <= 1.0)):
        raise ValueError(f"{name} must lie in [0, 1], got {array[~((array >= 0.0) & (array <= 1.0))][0]}")
    return array


def respond(
    true_object: np.ndarray,
    requested: np.ndarray,
    true_status: np.ndarray,
    true_code: np.ndarray,
    rng: np.random.Generator,
    p_reply=0.9,
    p_flip=0.0,
    p_code=0.0,
    *,
    false_reply_p: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """IFF replies of K plots: ``(iff_status[K] int8, code[K] int32)``, -1 where missing.

    ``true_object[K]``: index of each plot's object into ``true_status`` / ``true_code``
    (``-1`` = false plot); ``requested[K]``: whether the plot is interrogated;
    ``true_status[n_objects]``: 0 friend, 1 foe, 2 undetermined (never flipped), -1 no IFF
    transponder; ``true_code[n_objects]``: Mode 3/A as an integer in [0, 4095], -1 none.
    ``p_reply``, ``p_flip``, ``p_code``: scalars or arrays [n_objects].
    """
    true_object = np.asarray(true_object, dtype=np.int64)
    requested = np.asarray(requested, dtype=bool)
    true_status = np.asarray(true_status, dtype=np.int64)
    true_code = np.asarray(true_code, dtype=np.int64)
    count, n_objects = true_object.size, true_status.size
    if requested.shape != true_object.shape or true_object.ndim != 1:
        raise ValueError(f"true_object and requested must be 1-D of equal length, got {true_object.shape} and {requested.shape}")
    if true_code.shape != true_status.shape:
        raise ValueError(f"true_status and true_code must have one value per object, got {true_status.shape} and {true_code.shape}")
    if count and (true_object.min() < -1 or true_object.max() >= n_objects):
        raise ValueError(f"true_object must be -1 (false plot) or an object index in [0, {n_objects}), "
                         f"got values in [{true_object.min()}, {true_object.max()}]")
    if np.any((true_status < NO_REPLY) | (true_status > UNDETERMINED)):
        raise ValueError("true_status must be -1 (no IFF transponder), 0 (friend), 1 (foe) or 2 (undetermined)")
    if np.any((true_code < -1) | (true_code >= MODE3A_CODE_COUNT)):
        raise ValueError(f"true_code must be -1 (none) or a Mode 3/A code in [0, {MODE3A_CODE_COUNT - 1}]")
    if not 0.0 <= false_reply_p <= 1.0:
        raise ValueError(f"false_reply_p must lie in [0, 1], got {false_reply_p}")
    reply_p = _per_object("p_reply", p_reply, n_objects)
    flip_p = _per_object("p_flip", p_flip, n_objects)
    code_p = _per_object("p_code", p_code, n_objects)

    # every plot's draws, always and in this order: the stream does not depend on the mask or the p's
    uniform = rng.random((count, 3))  # reply, flip, code replacement
    code_offset = rng.integers(1, MODE3A_CODE_COUNT, size=count)  # other code = (true + offset) mod 4096
    false_status = rng.integers(FRIEND, FOE + 1, size=count)
    false_code = rng.integers(0, MODE3A_CODE_COUNT, size=count)

    is_object = true_object >= 0
    obj = np.where(is_object, true_object, 0)  # safe index; false plots are masked below
    status = true_status[obj] if n_objects else np.full(count, NO_REPLY)
    code = true_code[obj] if n_objects else np.full(count, -1)
    replies = requested & is_object & (status != NO_REPLY)
    if n_objects:
        replies &= uniform[:, 0] < reply_p[obj]
        flipped = (uniform[:, 1] < flip_p[obj]) & (status != UNDETERMINED)
        corrupted = (uniform[:, 2] < code_p[obj]) & (code >= 0)
    else:
        flipped = corrupted = np.zeros(count, dtype=bool)
    status = np.where(flipped, 1 - status, status)
    code = np.where(corrupted, (code + code_offset) % MODE3A_CODE_COUNT, code)

    false_replies = requested & ~is_object & (uniform[:, 0] < false_reply_p)
    out_status = np.full(count, NO_REPLY, dtype=np.int8)
    out_code = np.full(count, -1, dtype=np.int32)
    out_status[replies] = status[replies]
    out_code[replies] = code[replies]
    out_status[false_replies] = false_status[false_replies]
    out_code[false_replies] = false_code[false_replies]
    return out_status, out_code


def interrogation_mask(time: np.ndarray, policy: str | Sequence[Sequence[float]]) -> np.ndarray:
    """Which plots are interrogated: ``always``, ``never``, or the plots whose time lies in one
    of the closed windows ``[[start, end], ...]`` (seconds)."""
    time = np.asarray(time, dtype=float)
    if isinstance(policy, str):
        if policy not in INTERROGATION_POLICIES:
            raise ValueError(f"interrogation policy must be always, never or a list of [start, end] windows, got {policy!r}")
        return np.full(time.shape, policy == "always")
    mask = np.zeros(time.shape, dtype=bool)
    for start, end in policy:
        mask |= (time >= start) & (time <= end)
    return mask


def mode3a_int(code: str | None) -> int:
    """A Mode 3/A code's text ("1234") as the integer ``int(code, 8)``; None -> -1."""
    return -1 if code is None else int(code, 8)
