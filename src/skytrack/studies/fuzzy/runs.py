"""Monte Carlo runs of spec 003's airborne scenarios as batches for the studies' tracker.

:func:`simulate_runs` simulates ``runs`` seeded runs of an
:class:`~skytrack.sim.airborne.AirborneScenario` (R17), draws for every plot the IFF reply it would
carry if interrogated (:func:`skytrack.sim.iff.respond` on the run's own IFF stream, R18), and
packs them into :class:`~skytrack.studies.fuzzy.paper_tracker.RunPlots` ``[runs, scans, slots]``
with the scan's emission order kept in the slot order.  Run ``i`` uses seed
``SeedSequence(seed).spawn(runs)[i]``, so a run's plots do not depend on how many runs are drawn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.sim.airborne import AirborneScenario, simulate_airborne
from skytrack.sim.iff import respond
from skytrack.studies.fuzzy.paper_tracker import RunPlots


@dataclass(frozen=True)
class IffSettings:
    """The responder's probabilities (R18; spec 003 defaults)."""

    p_reply: float = 0.9
    p_flip: float = 0.0
    p_code: float = 0.0


@dataclass
class SimulatedRuns:
    """The batch for the tracker plus each plot's true object ``[R, S, M]`` (-1 = false or empty)."""

    plots: RunPlots
    truth: np.ndarray
    crossing_scan: int | None


def simulate_runs(scenario: AirborneScenario, runs: int, seed: int, iff: IffSettings = IffSettings()) -> SimulatedRuns:
    """``runs`` runs of ``scenario`` packed for :class:`~skytrack.studies.fuzzy.paper_tracker.PaperTracker`."""
    children = np.random.SeedSequence(seed).spawn(runs)
    simulated = [simulate_airborne(scenario, child) for child in children]
    n_scans = scenario.n_scans
    slots = max(int(np.bincount(run.scan, minlength=n_scans).max()) if len(run) else 0 for run in simulated)
    slots = max(slots, 1)
    m = simulated[0].noise.shape[-1]
    shape = (runs, n_scans, slots)
    z = np.zeros(shape + (m,))
    valid = np.zeros(shape, dtype=bool)
    truth = np.full(shape, -1, dtype=np.int64)
    reply_iff = np.full(shape, -1, dtype=np.int64)
    reply_code = np.full(shape, -1, dtype=np.int64)
    first = simulated[0].true
    own_p = np.broadcast_to(first.own_p, (runs, n_scans, 3)).copy()
    own_v = np.broadcast_to(first.own_v, (runs, n_scans, 3)).copy()
    for r, run in enumerate(simulated):
        if not len(run):
            continue
        starts = np.searchsorted(run.scan, run.scan, side="left")
        rank = np.arange(len(run)) - starts  # position in the scan's emission order
        z[r, run.scan, rank] = run.measurements
        valid[r, run.scan, rank] = True
        truth[r, run.scan, rank] = run.truth
        status, code = respond(run.truth, np.ones(len(run), dtype=bool), run.target_status, run.target_code,
                               run.iff_rng, iff.p_reply, iff.p_flip, iff.p_code)
        reply_iff[r, run.scan, rank] = status
        reply_code[r, run.scan, rank] = code
    plots = RunPlots(first.t, z, valid, own_p, own_v, simulated[0].noise, reply_iff, reply_code)
    return SimulatedRuns(plots, truth, scenario.crossing_scan)
