"""Track-to-track identification scored against truth (issue 9: radar ↔ radar, radar ↔ interrogator).

:func:`score_track_pairs` takes the pairs an identification decided over time (``time``,
``track_id`` of system 1, ``other_track`` of system 2) and both systems' tracks tables, finds
the truth object of every track row (:mod:`skytrack.analysis.row_association`: the cut-off
matching of :mod:`skytrack.analysis.evaluate`, then along each track) and counts:

* pair rows whose two tracks are on one object (correct), on two objects (wrong), or not both
  on an object at that time (unjudged: a false track, or a track that has just lost its object);
* per object seen by both systems for at least ``min_both_s``: whether it was paired, when first
  (time to pair, from the first instant both systems tracked it) and on which share of the
  instants from ``min_both_s`` after that on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from skytrack.analysis.evaluate import DEFAULT_GATE_M
from skytrack.analysis.row_association import associate_rows, existing_objects, smooth_along_tracks
from skytrack.analysis.truth import _prepare_truth


@dataclass(frozen=True)
class PairScore:
    """Totals and the per-object table of :func:`score_track_pairs`."""

    totals: dict
    per_object: pd.DataFrame

    @property
    def passed(self) -> bool:
        """No wrong pair, and every object both systems tracked long enough was paired."""
        return self.totals["wrong_pair_rows"] == 0 and self.totals["objects_paired"] == self.totals["objects_both"]

    def to_dict(self) -> dict:
        return {"totals": self.totals, "per_object": self.per_object.to_dict("records"), "passed": self.passed}


def _truth_of_rows(tracks: pd.DataFrame, truth: pd.DataFrame, cutoff: float) -> np.ndarray:
    axes = ["x", "y"]
    prepared, _ = _prepare_truth(truth, axes, [])
    rows = tracks.reset_index(drop=True)
    row_target, step, _, t_target, t_step, _ = associate_rows(rows, prepared, axes, cutoff, 1e-3)
    row_target = smooth_along_tracks(row_target, rows["track_id"].to_numpy(), rows["time"].to_numpy(float))
    row_target = existing_objects(step, row_target, t_step, t_target)
    names = np.asarray(prepared.target_ids, dtype=object)
    return np.where(row_target >= 0, names[np.maximum(row_target, 0)], None)


def score_track_pairs(pairs: pd.DataFrame, tracks_first: pd.DataFrame, tracks_second: pd.DataFrame,
                      truth: pd.DataFrame, *, cutoff_m: float = DEFAULT_GATE_M, min_both_s: float = 60.0) -> PairScore:
    """Score decided pairs against truth (module docstring)."""
    first = tracks_first.reset_index(drop=True).assign(truth=_truth_of_rows(tracks_first, truth, cutoff_m))
    second = tracks_second.reset_index(drop=True).assign(truth=_truth_of_rows(tracks_second, truth, cutoff_m))
    pairs = pairs.sort_values("time", kind="stable").reset_index(drop=True)
    # the object of each pair's first-system track at the pair's time (the row itself)
    left = pd.merge(pairs[["time", "track_id", "other_track"]], first[["time", "track_id", "truth"]],
                    on=["time", "track_id"], how="left")
    # the other system's rows are at its own instants: take its latest row at or before the pair's time
    other = second[["time", "track_id", "truth"]].rename(columns={"track_id": "other_track", "truth": "other_truth"})
    other["other_track"] = other["other_track"].astype(str)
    left["other_track"] = left["other_track"].astype(str)
    joined = pd.merge_asof(left.sort_values("time"), other.sort_values("time"), on="time", by="other_track",
                           direction="backward", tolerance=30.0)
    judged = joined["truth"].notna() & joined["other_truth"].notna()
    correct = judged & (joined["truth"] == joined["other_truth"])
    wrong = judged & ~correct
    rows = []
    seen_first = first.dropna(subset=["truth"]).groupby("truth")["time"].agg(["min", "max"])
    seen_second = second.dropna(subset=["truth"]).groupby("truth")["time"].agg(["min", "max"])
    paired_rows = joined[correct]
    for target in seen_first.index.intersection(seen_second.index):
        start = max(seen_first.at[target, "min"], seen_second.at[target, "min"])
        stop = min(seen_first.at[target, "max"], seen_second.at[target, "max"])
        if stop - start < min_both_s:
            continue
        mine = paired_rows[paired_rows["truth"] == target]
        instants = first[(first["truth"] == target) & (first["time"] >= start + min_both_s) & (first["time"] <= stop)]
        held = np.isin(instants["time"].to_numpy(), mine["time"].to_numpy()).mean() if len(instants) else np.nan
        rows.append({"target_id": target, "both_from_s": start, "both_until_s": stop,
                     "first_paired_s": mine["time"].min() if len(mine) else np.nan,
                     "time_to_pair_s": (mine["time"].min() - start) if len(mine) else np.nan,
                     "paired_share_after": held})
    per_object = pd.DataFrame(rows, columns=["target_id", "both_from_s", "both_until_s", "first_paired_s",
                                             "time_to_pair_s", "paired_share_after"])
    paired = per_object["time_to_pair_s"].notna() & (per_object["time_to_pair_s"] <= min_both_s)
    totals = {"pair_rows": int(len(joined)), "correct_pair_rows": int(correct.sum()), "wrong_pair_rows": int(wrong.sum()),
              "unjudged_pair_rows": int((~judged).sum()), "objects_both": int(len(per_object)),
              "objects_paired": int(paired.sum()),
              "median_time_to_pair_s": float(per_object["time_to_pair_s"].median()) if len(per_object) else None}
    return PairScore(totals, per_object)
