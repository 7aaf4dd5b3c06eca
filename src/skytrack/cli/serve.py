"""``skytrack serve`` and ``skytrack replay`` (issue 11 items 3 and 5): the live service and its feed.

The service itself is :mod:`skytrack.service` (imported inside the commands, so ``skytrack --help``
stays fast); this module parses the options, prints where to look, and shows replay progress.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console

console = Console()
error_console = Console(stderr=True)


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {message}", highlight=False)
    raise typer.Exit(2)


def _tracker_config(config_file: Optional[Path], filter_kind: Optional[str], output_interval: Optional[float]):
    from skytrack.tracker import TrackerConfig

    config = TrackerConfig.from_file(config_file) if config_file is not None else TrackerConfig()
    if filter_kind is not None:
        config = config.replace(filter_kind=filter_kind)
    if output_interval is not None:
        config = config.replace(output_interval_s=output_interval)
    return config


def serve(
    sensors: Annotated[Optional[Path], typer.Option("--sensors", help="sensors.json of the radars (SAC/SIC: the sensors' sac/sic fields, else 0/position).")] = None,
    udp: Annotated[str, typer.Option("--udp", help="UDP address to receive ASTERIX on, HOST:PORT; a 224-239.x.x.x host joins that multicast group.")] = "0.0.0.0:30048",
    http: Annotated[str, typer.Option("--http", help="HTTP address of the display, /ws, /health and /metrics.")] = "127.0.0.1:8080",
    reorder_window_s: Annotated[float, typer.Option("--reorder-window-s", help="Plots are held this long (plot time) to be put in time order; older ones arriving later are counted as late.")] = 2.0,
    checkpoint_dir: Annotated[Optional[Path], typer.Option("--checkpoint-dir", help="Write the tracker's state here, and resume from it at start.")] = None,
    checkpoint_every_s: Annotated[float, typer.Option("--checkpoint-every-s", help="Seconds between checkpoints.")] = 10.0,
    filter_kind: Annotated[Optional[str], typer.Option("--filter", help="Filter family (as `skytrack track --filter`).")] = None,
    config_file: Annotated[Optional[Path], typer.Option("--config", help="Tracker configuration file (YAML or JSON).")] = None,
    output_interval: Annotated[Optional[float], typer.Option("--output-interval", help="A frame every N s of plot time (default: each scan of the first radar).")] = None,
    adsb: Annotated[Optional[Path], typer.Option("--adsb", help="ADS-B reports file: label the tracks with the icao24/callsign spec 001's test decides.")] = None,
    demo: Annotated[bool, typer.Option("--demo", help="Simulate the demo scenario (radar + ADS-B) and feed it live into the service.")] = False,
    speed: Annotated[float, typer.Option("--speed", help="With --demo: real time x this.")] = 1.0,
) -> None:
    """Run the live tracking service: ASTERIX CAT048 over UDP in, tracks to the browser display over WebSocket."""
    from skytrack.service.app import parse_address
    from skytrack.service.server import build_service, run_server

    try:
        udp_address = parse_address(udp, "0.0.0.0")
        http_address = parse_address(http, "127.0.0.1")
        config = _tracker_config(config_file, filter_kind, output_interval)
    except ValueError as error:
        _fail(str(error))
    feed = None
    sensor_set = None
    if demo:
        if sensors is not None or adsb is not None:
            _fail("--demo simulates its own sensors and ADS-B: leave out --sensors and --adsb")
        from skytrack.service.demo import demo_feed

        with console.status("simulating the demo scenario..."):
            target = ("127.0.0.1" if udp_address[0] in ("0.0.0.0", "") else udp_address[0], udp_address[1])
            feed = demo_feed(target, speed=speed)
        sensor_set = feed.sensors
        console.print(f"demo: {feed.plots} plots over {feed.duration_s:.0f} s of {', '.join(sensor_set.names)}"
                      + ("" if feed.adsb is not None else " (the scenario has no ADS-B: tracks stay unlabelled)"))
    elif sensors is None:
        _fail("--sensors is required (or --demo)")
    try:
        service = build_service(sensors, udp_address, config=config, window_s=reorder_window_s,
                                checkpoint_dir=checkpoint_dir, checkpoint_every_s=checkpoint_every_s,
                                adsb=adsb if feed is None else feed.adsb, sensors=sensor_set,
                                log=lambda text: console.print(text, highlight=False))
    except (ValueError, OSError) as error:
        _fail(str(error))

    def started() -> None:
        console.print(f"listening for ASTERIX on udp://{service.udp_bound[0]}:{service.udp_bound[1]}")
        console.print(f"display: [bold]http://{http_address[0]}:{http_address[1]}/[/]  (health: /health, "
                      "metrics: /metrics, frames: /ws)  Ctrl-C stops", highlight=False)
        if feed is not None:
            def run_feed():
                report = feed.replayer.run()
                console.print(f"demo traffic ended ({report.records} plots sent); the service keeps running")

            threading.Thread(target=run_feed, daemon=True, name="demo-feed").start()

    try:
        run_server(service, http_address, on_started=started)
    except KeyboardInterrupt:
        pass
    except OSError as error:
        _fail(str(error))
    finally:
        if feed is not None:
            feed.replayer.stop()


def replay(
    recording: Annotated[Path, typer.Argument(help="ASTERIX file (.ast) or plots table (.parquet/.csv, encoded to CAT048 on the fly).")],
    to: Annotated[str, typer.Option("--to", help="Destination, udp://HOST:PORT.")] = "udp://127.0.0.1:30048",
    speed: Annotated[float, typer.Option("--speed", help="Real time x this.")] = 1.0,
    loop: Annotated[bool, typer.Option("--loop", help="Send again and again, each pass later (time of day rewritten).")] = False,
    sensors: Annotated[Optional[Path], typer.Option("--sensors", help="sensors.json (needed for a plots table: SAC/SIC and epoch; its largest scan period is the loop period).")] = None,
    max_datagram: Annotated[int, typer.Option("--max-datagram", help="Largest datagram (bytes); up to 65507 on loopback.")] = 1400,
    loop_period_s: Annotated[Optional[float], typer.Option("--loop-period-s", help="Passes of --loop are whole multiples of this apart (default: the largest scan period, else 1 s).")] = None,
    duration_s: Annotated[Optional[float], typer.Option("--duration-s", help="Stop after this many seconds of wall time.")] = None,
    send_log: Annotated[Optional[Path], typer.Option("--send-log", help="Write (record time of day, wall time sent) per datagram, float64 pairs (benchmarks).")] = None,
) -> None:
    """Send a recording as ASTERIX UDP datagrams, paced by the plots' times."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from skytrack.service.app import parse_address
    from skytrack.service.replay import Replayer, load_recording

    if not to.startswith("udp://"):
        _fail(f"--to must look like udp://HOST:PORT, got {to!r}")
    try:
        address = parse_address(to[len("udp://"):], "127.0.0.1")
        sensor_set = None
        if sensors is not None:
            from skytrack.io import read_sensors

            sensor_set = read_sensors(sensors)
        periods = [s.scan_period_s for s in (sensor_set.sensors if sensor_set else []) if s.scan_period_s]
        period = loop_period_s if loop_period_s is not None else (max(periods) if periods else 1.0)
        data = load_recording(recording, sensor_set, max_datagram)
        replayer = Replayer(data, address, speed=speed, loop=loop, loop_period_s=period,
                            max_datagram_bytes=max_datagram, send_log=send_log)
    except (ValueError, OSError, KeyError) as error:
        _fail(str(error))
    if data.records == 0:
        _fail(f"{recording}: no ASTERIX record to send")
    console.print(f"{recording}: {data.records} records ({data.plots} CAT048 plots) in {len(replayer.bounds) - 1} "
                  f"datagrams over "
                  f"{data.span_s:.1f} s; sending to udp://{address[0]}:{address[1]} at x{speed:g}"
                  + (f", looping every {replayer.shift_s:g} s of record time" if loop else ""), highlight=False)
    if replayer.oversize:
        console.print(f"[yellow]note:[/] {replayer.oversize} datagrams are longer than {max_datagram} bytes "
                      "(recorded blocks that long are sent whole; fine on loopback)")
    total = None if loop else data.records
    display = Progress(TextColumn("[bold]replay"), BarColumn(), TextColumn("{task.completed:,.0f} records"),
                       TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), console=error_console)
    with display:
        task = display.add_task("replay", total=total, rate="")

        def progress(report) -> None:
            done = report.records if total is None else min(report.records, total)
            display.update(task, completed=done, rate=f"{report.plots_per_s:,.0f} plots/s")

        try:
            report = replayer.run(progress, duration_s=duration_s)
        except KeyboardInterrupt:
            replayer.stop()
            return
    console.print(f"sent {report.records} records ({report.plots} plots) in {report.datagrams} datagrams "
                  f"({report.bytes} bytes, "
                  f"{report.passes} pass{'es' if report.passes != 1 else ''}) in {report.elapsed_s:.1f} s: "
                  f"{report.plots_per_s:,.0f} plots/s; at most {report.max_behind_s * 1000:.0f} ms behind schedule",
                  soft_wrap=True)


def register_serve(app: typer.Typer) -> None:
    """Add ``serve`` and ``replay`` to the ``skytrack`` command."""
    app.command()(serve)
    app.command()(replay)
