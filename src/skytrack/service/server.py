"""Starting ``skytrack serve`` (issue 11 items 3 and 5): sensors, tracker or checkpoint, the app on uvicorn.

:func:`build_service` reads sensors.json, builds the tracker (or resumes it from the checkpoint in
``checkpoint_dir``: a damaged or unusable checkpoint is reported, set aside as ``*.damaged`` and the
service starts fresh), the ADS-B labeller (``adsb``: a reports file; the tracks are labelled with the
identities spec 001's sequential test decides) and the :class:`~skytrack.service.app.LiveService`.
:func:`run_server` runs the app on uvicorn until Ctrl-C; ``on_started`` is called once the UDP port and
HTTP port are open (``skytrack serve --demo`` starts its in-process replay there).
"""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Callable
from pathlib import Path

from skytrack.service.live_adsb import build_labeler

CHECKPOINT_NAME = "skytrack.checkpoint.npz"
__all__ = ["CHECKPOINT_NAME", "build_labeler", "build_service", "resume_or_start", "run_server"]


def resume_or_start(sensors, config, checkpoint_dir: Path | None, labeler, log=print):
    """``(tracker, labeler, resumed_from)``: the checkpoint's tracker when ``checkpoint_dir`` holds a usable
    one, else a new tracker (saying why)."""
    from skytrack.tracker import Tracker

    if checkpoint_dir is None:
        return Tracker(sensors, config), labeler, None
    checkpoint_dir.mkdir(parents=True, exist_ok=True)
    path = checkpoint_dir / CHECKPOINT_NAME
    if not path.exists():
        log(f"no checkpoint in {checkpoint_dir}: starting fresh (checkpoints go to {path})")
        return Tracker(sensors, config), labeler, None
    from skytrack.app.checkpoint import CheckpointError, load_checkpoint, read_checkpoint

    try:
        tracker, saved_labeler = load_checkpoint(path, sensors, config)
        header, _ = read_checkpoint(path)
    except CheckpointError as error:
        aside = path.with_name(path.name + ".damaged")
        path.replace(aside)
        log(f"CHECKPOINT NOT USED: {error}. Starting fresh; the file was moved to {aside}")
        return Tracker(sensors, config), labeler, None
    if labeler is not None and saved_labeler is None:
        log("the checkpoint has no ADS-B labelling state: labelling starts afresh with --adsb")
    labeler = saved_labeler if saved_labeler is not None else labeler
    log(f"resumed from checkpoint {path}: {header.get('tracks')} tracks ({header.get('confirmed_tracks')} confirmed), "
        f"last plot at {header.get('last_plot_s')} s since the epoch")
    return tracker, labeler, str(path)


def build_service(sensors_path, udp: tuple[str, int], *, config=None, window_s: float = 2.0,
                  checkpoint_dir: Path | None = None, checkpoint_every_s: float = 10.0, adsb=None,
                  sensors=None, tick_s: float = 0.05, log=print):
    """The :class:`~skytrack.service.app.LiveService` of a sensors.json (or a given sensor set)."""
    from skytrack.io import read_sensors
    from skytrack.service.app import LiveService
    from skytrack.service.pipeline import LivePipeline

    sensors = sensors if sensors is not None else read_sensors(sensors_path)
    if not checkpoint_every_s > 0:
        raise ValueError(f"--checkpoint-every-s must be > 0, got {checkpoint_every_s}")
    labeler = build_labeler(adsb, sensors) if adsb is not None else None
    checkpoint_dir = None if checkpoint_dir is None else Path(checkpoint_dir)
    tracker, labeler, resumed_from = resume_or_start(sensors, config, checkpoint_dir, labeler, log)
    pipeline = LivePipeline(sensors, tracker, window_s, labeler, feed_adsb=adsb is None)
    checkpoint_path = None if checkpoint_dir is None else checkpoint_dir / CHECKPOINT_NAME
    return LiveService(pipeline, udp, checkpoint_path=checkpoint_path, checkpoint_every_s=checkpoint_every_s,
                       tick_s=tick_s, resumed_from=resumed_from, log=log)


def run_server(service, http: tuple[str, int], on_started: Callable[[], None] | None = None,
               stop: threading.Event | None = None) -> None:
    """Serve the app on uvicorn until Ctrl-C (or ``stop`` is set)."""
    import uvicorn

    from skytrack.service.app import build_app

    app = build_app(service)
    server = uvicorn.Server(uvicorn.Config(app, host=http[0], port=http[1], log_level="warning", lifespan="on",
                                           ws="websockets-sansio"))

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:  # a clear error before uvicorn's own
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(http)
        except OSError as error:
            raise OSError(error.errno, f"cannot serve HTTP on {http[0]}:{http[1]}: {error.strerror}") from None

    async def main():
        await service.start()  # the UDP port: its error comes out here, plainly (the app's lifespan then reuses it)
        serving = asyncio.create_task(server.serve())
        while not server.started:
            if serving.done():
                await serving  # a startup error (port in use...) surfaces here
                return
            await asyncio.sleep(0.05)
        if on_started is not None:
            on_started()
        while not serving.done():
            if stop is not None and stop.is_set():
                server.should_exit = True
            await asyncio.sleep(0.1)
        await serving

    asyncio.run(main())
