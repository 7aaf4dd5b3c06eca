"""``skytrack serve --demo`` (issue 11 item 3): the demo scenario's traffic fed live into the service.

:func:`demo_feed` simulates the bundled demo scenario (:func:`skytrack.app.simulate.run_simulation`: one
radar with SSR, 78 aircraft, clutter, ADS-B), encodes its plots to CAT048 (:func:`skytrack.io.asterix.recording.encode_recording`)
and returns the sensor set, the ADS-B reports (the service labels the tracks with them: spec 001's
sequential test, :class:`~skytrack.app.identification.TrackLabeler`) and a :class:`~skytrack.service.replay.Replayer`
ready to send the plots to the service's UDP port in real time (``speed``).  The ADS-B reports are given to
the labeller as a table, not sent as CAT021: the labeller reads the reports up to each track row's time, so
it does not see the future.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class DemoFeed:
    sensors: object
    adsb: object
    replayer: object
    plots: int
    duration_s: float


def demo_feed(udp: tuple[str, int], *, scenario: str = "demo", seed: int | None = None,
              speed: float = 1.0) -> DemoFeed:
    """The simulated demo traffic, ready to replay to ``udp`` (see the module docstring)."""
    from skytrack.app.simulate import run_simulation
    from skytrack.io.asterix.recording import SECTOR_BLOCK_S, encode_recording
    from skytrack.service.pipeline import sensor_sac_sic, time_of_day_at_epoch
    from skytrack.service.replay import DEFAULT_DATAGRAM_BYTES, MAX_RECORD_BYTES, Replayer, scan_blocks

    result = run_simulation(scenario, seed)
    sensors = result.sensors
    plots = result.plots[result.plots["sensor"].isin([s.name for s in sensors.sensors if s.is_radar])]
    data = encode_recording(plots, sensor_sac_sic(sensors),
                            time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc),
                            max_records_per_block=(DEFAULT_DATAGRAM_BYTES - 3) // MAX_RECORD_BYTES,
                            block_span_s=SECTOR_BLOCK_S)
    recording = scan_blocks(np.frombuffer(data, np.uint8))
    replayer = Replayer(recording, udp, speed=speed)
    adsb = result.adsb if result.adsb is not None and len(result.adsb) else None
    return DemoFeed(sensors, adsb, replayer, len(plots), recording.span_s)
