"""Report figures: a PPI-style plan view of plots, truth and tracks, and metrics over time.

Figures are drawn with matplotlib's object API on an Agg canvas (``matplotlib.figure.Figure``,
never ``pyplot``), so nothing is displayed and no global backend is changed.

Plot positions (:func:`plot_positions`) come from the plots table (docs/formats.md) through
the tracker's own placement, :func:`skytrack.models.conversion.place_plots`:

* a plot with a measured ``elevation_deg`` is placed in polar coordinates;
* a 2-D radar plot with a Mode C altitude (or ``default_altitude_m`` when given) is placed on
  the sphere model (docs/formats.md, 2-D radar);
* any other plot is drawn at its slant range projected horizontally (elevation 0 in the
  sensor frame), the classical PPI display; the figure's footnote counts each case;

in the common ENU frame (per-plot platform positions ``platform_x/y/z`` for airborne radars).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd
import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

from skytrack.geo import Sensor, SensorSet
from skytrack.models.conversion import place_plots

__all__ = ["plot_positions", "plot_ppi", "plot_metrics_over_time"]

FT_TO_M = 0.3048
_KM = 1000.0
PROJECTION_ELEVATION = "measured elevation"
PROJECTION_ALTITUDE = "slant range at Mode C altitude"
PROJECTION_DEFAULT_ALTITUDE = "slant range at default altitude"
PROJECTION_HORIZONTAL = "slant range projected horizontally"


def _py(value):
    return value.item() if isinstance(value, np.generic) else value


def _sensor_map(sensors: SensorSet | Iterable[Sensor]) -> dict[str, Sensor]:
    items = sensors.sensors if isinstance(sensors, SensorSet) else list(sensors)
    return {s.name: s for s in items}


def plot_positions(plots: pd.DataFrame, sensors: SensorSet | Iterable[Sensor], default_altitude_m: float | None = None) -> pd.DataFrame:
    """Common-frame ``x, y, z`` of every plot and the ``projection`` used (module docstring).

    Returns a frame with the index of ``plots``.  An unknown sensor name or a missing
    required column raises a ``ValueError`` naming the row/column.
    """
    for column in ("sensor", "range_m", "azimuth_deg"):
        if column not in plots.columns:
            raise ValueError(f"plots table: missing required column {column!r}")
    by_name = _sensor_map(sensors)
    names = plots["sensor"].astype(str).to_numpy()
    unknown = ~np.isin(names, list(by_name))
    if np.any(unknown):
        k = int(np.flatnonzero(unknown)[0])
        raise ValueError(f"plots table, row {_py(plots.index[k])!r}, column 'sensor': unknown sensor {names[k]!r} "
                         f"(known: {', '.join(by_name) or 'none'})")
    r = plots["range_m"].to_numpy(dtype=float, na_value=np.nan)
    az = np.radians(plots["azimuth_deg"].to_numpy(dtype=float, na_value=np.nan))
    bad = ~(np.isfinite(r) & np.isfinite(az))
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        column = "range_m" if not np.isfinite(r[k]) else "azimuth_deg"
        raise ValueError(f"plots table, row {_py(plots.index[k])!r}, column {column!r}: value is null or not finite")
    el = np.radians(plots["elevation_deg"].to_numpy(dtype=float, na_value=np.nan)) if "elevation_deg" in plots else np.full(r.size, np.nan)
    alt = plots["mode_c_ft"].to_numpy(dtype=float, na_value=np.nan) * FT_TO_M if "mode_c_ft" in plots else np.full(r.size, np.nan)
    xyz = np.zeros((r.size, 3))
    projection = np.empty(r.size, dtype=object)
    for name in np.unique(names):
        rows = np.flatnonzero(names == name)
        sensor = by_name[name]
        has_el = np.isfinite(el[rows])
        has_alt = ~has_el & np.isfinite(alt[rows])
        use_default = ~has_el & ~has_alt & (default_altitude_m is not None)
        flat = ~has_el & ~has_alt & ~use_default
        platform = None
        if sensor.is_moving:
            columns = [f"platform_{c}" for c in ("x", "y", "z", "vx", "vy", "vz")]
            if not all(c in plots.columns for c in columns[:3]):
                raise ValueError(f"plots table: airborne sensor {name!r} needs columns {', '.join(columns[:3])}")
            platform = np.column_stack([plots[c].to_numpy(dtype=float) if c in plots.columns
                                        else np.zeros(len(plots)) for c in columns])[rows]
        elevation = np.where(flat, 0.0, el[rows])
        height = np.where(has_alt, alt[rows], default_altitude_m if default_altitude_m is not None else np.nan)
        xyz[rows], _ = place_plots(sensor, r[rows], az[rows], elevation, height, platform)
        projection[rows] = np.select(
            [has_el, has_alt, use_default], [PROJECTION_ELEVATION, PROJECTION_ALTITUDE, PROJECTION_DEFAULT_ALTITUDE],
            PROJECTION_HORIZONTAL,
        )
    return pd.DataFrame({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "projection": projection}, index=plots.index)


def _in_window(frame: pd.DataFrame | None, window: tuple[float, float] | None) -> pd.DataFrame | None:
    if frame is None or window is None or len(frame) == 0:
        return frame
    t = frame["time"].to_numpy(dtype=float)
    return frame[(t >= window[0]) & (t <= window[1])]


def _lines(frame: pd.DataFrame, keys: list[str]) -> list[np.ndarray]:
    """Polylines in km, one per group of ``keys``, ordered by time."""
    if frame is None or len(frame) == 0:
        return []
    ordered = frame.sort_values([*keys, "time"], kind="stable")
    xy = ordered[["x", "y"]].to_numpy(dtype=float) / _KM
    group = ordered.groupby(keys, sort=False).ngroup().to_numpy()
    cuts = np.flatnonzero(np.diff(group)) + 1
    return [line for line in np.split(xy, cuts) if len(line) >= 2]


def _nice_step(span_km: float) -> float:
    raw = span_km / 5.0
    magnitude = 10 ** math.floor(math.log10(raw)) if raw > 0 else 1.0
    for factor in (1, 2, 2.5, 5, 10):
        if raw <= factor * magnitude:
            return factor * magnitude
    return 10 * magnitude


def _is_false_plot(plots: pd.DataFrame) -> np.ndarray | None:
    if "truth_id" not in plots.columns:
        return None
    ids = plots["truth_id"]
    return (ids.isna() | (ids.astype(str) == "")).to_numpy()


#: truth: wide and light, under the tracks; tracks: thin, on top
TRUTH_COLOUR = "0.78"
TRUTH_WIDTH = 3.0
TRACK_WIDTH = 1.0


def plot_ppi(
    plots_df: pd.DataFrame | None,
    truth_df: pd.DataFrame | None,
    tracks_df: pd.DataFrame | None,
    sensors: SensorSet | Iterable[Sensor],
    path: str | Path,
    *,
    time_window: tuple[float, float] | None = None,
    default_altitude_m: float | None = None,
    n_track_labels: int = 15,
    ring_spacing_km: float | None = None,
    extent_km: tuple[float, float, float, float] | None = None,
    title: str | None = None,
    figsize: tuple[float, float] = (10.0, 10.0),
    dpi: int = 150,
) -> Path:
    """Plan view around the radar(s): range rings, false plots grey, target plots faint colours,
    truth lines, track lines with ids for the ``n_track_labels`` longest tracks; axes in km.

    ``time_window = (t0, t1)`` restricts every table to that span.  Target vs false plots
    use the simulator's ``truth_id`` column when present (``""`` or null = false plot).
    Returns the written path; :func:`ppi_figure` gives the figure.
    """
    path = Path(path)
    fig = ppi_figure(plots_df, truth_df, tracks_df, sensors, time_window=time_window,
                     default_altitude_m=default_altitude_m, n_track_labels=n_track_labels,
                     ring_spacing_km=ring_spacing_km, extent_km=extent_km, title=title, figsize=figsize, dpi=dpi)
    fig.savefig(path)
    return path


#: track line styles: 20 colours x 3 dash patterns, so that 60 tracks in view look different
TRACK_COLOURS = tuple(matplotlib.colormaps["tab20"].colors)
TRACK_DASHES = ("solid", (0, (6, 2)), (0, (1.5, 1.5)))


def track_styles(count: int) -> list[tuple[tuple[float, ...], object]]:
    """(colour, line style) of ``count`` tracks: the 20 colours first solid, then dashed, then dotted."""
    return [(TRACK_COLOURS[k % len(TRACK_COLOURS)], TRACK_DASHES[(k // len(TRACK_COLOURS)) % len(TRACK_DASHES)])
            for k in range(count)]


def ppi_figure(
    plots_df: pd.DataFrame | None,
    truth_df: pd.DataFrame | None,
    tracks_df: pd.DataFrame | None,
    sensors: SensorSet | Iterable[Sensor],
    *,
    time_window: tuple[float, float] | None = None,
    default_altitude_m: float | None = None,
    n_track_labels: int = 15,
    ring_spacing_km: float | None = None,
    extent_km: tuple[float, float, float, float] | None = None,
    title: str | None = None,
    figsize: tuple[float, float] = (10.0, 10.0),
    dpi: int = 150,
) -> Figure:
    """The figure of :func:`plot_ppi`.  Truth is drawn as wide light lines under the tracks
    and the target plots as small dots over them, so that neither hides the other; tracks
    take 60 distinct colour and dash styles."""
    by_name = _sensor_map(sensors)
    plots_df, truth_df, tracks_df = (_in_window(f, time_window) for f in (plots_df, truth_df, tracks_df))
    fig = Figure(figsize=figsize, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    handles: list = []
    footnote = []
    n_plots = 0
    if plots_df is not None and len(plots_df):
        pos = plot_positions(plots_df, by_name.values(), default_altitude_m)
        n_plots = len(pos)
        xy = pos[["x", "y"]].to_numpy() / _KM
        false = _is_false_plot(plots_df)
        if false is None:
            ax.scatter(xy[:, 0], xy[:, 1], s=2, c="0.55", lw=0, rasterized=True, zorder=1)
            handles.append(Line2D([], [], ls="", marker="o", ms=4, color="0.55", label=f"plots ({n_plots}, origin unknown)"))
        else:
            ax.scatter(xy[false, 0], xy[false, 1], s=2, c="0.65", lw=0, rasterized=True, zorder=1)
            codes = pd.factorize(plots_df["truth_id"].astype(str).to_numpy()[~false])[0]
            ax.scatter(xy[~false, 0], xy[~false, 1], s=2.5, c=codes % 20, cmap="tab20", vmin=0, vmax=19, alpha=0.6, lw=0,
                       rasterized=True, zorder=5)
            handles.append(Line2D([], [], ls="", marker="o", ms=4, color="0.65", label=f"false / clutter plots ({int(false.sum())})"))
            handles.append(Line2D([], [], ls="", marker="o", ms=4, color="tab:blue", alpha=0.5,
                                  label=f"target plots ({int((~false).sum())}, colour per target)"))
        counts = pos["projection"].value_counts()
        footnote.append("plots: " + "; ".join(f"{n} {kind}" for kind, n in counts.items()))
    if truth_df is not None and len(truth_df):
        keys = ["target_id", "segment"] if "segment" in truth_df.columns else ["target_id"]
        lines = _lines(truth_df, keys)
        ax.add_collection(LineCollection(lines, colors=TRUTH_COLOUR, linewidths=TRUTH_WIDTH, zorder=2,
                                         capstyle="round", label="truth"))
        handles.append(Line2D([], [], color=TRUTH_COLOUR, lw=TRUTH_WIDTH,
                              label=f"truth ({truth_df['target_id'].nunique()} objects)"))
    n_tracks = 0
    if tracks_df is not None and len(tracks_df):
        lines = _lines(tracks_df, ["track_id"])
        ids = np.sort(tracks_df["track_id"].unique())
        n_tracks = ids.size
        styles = track_styles(len(lines))
        ax.add_collection(LineCollection(lines, colors=[c for c, _ in styles], linestyles=[d for _, d in styles],
                                         linewidths=TRACK_WIDTH, zorder=4, label="tracks"))
        handles.append(Line2D([], [], color=TRACK_COLOURS[0], lw=TRACK_WIDTH,
                              label=f"tracks ({n_tracks}, {min(n_tracks, 60)} styles; ids on the "
                                    f"{min(n_track_labels, n_tracks)} longest)"))
        lengths = tracks_df.groupby("track_id").size().sort_values(ascending=False, kind="stable")
        last = tracks_df.sort_values("time").groupby("track_id")[["x", "y"]].last()
        for track_id in lengths.index[:n_track_labels]:
            x, y = last.loc[track_id] / _KM
            ax.annotate(str(track_id), (x, y), xytext=(3, 3), textcoords="offset points", fontsize=7, zorder=6,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.7))
    radars = [s for s in by_name.values() if s.is_radar]
    _draw_radars(ax, radars, ring_spacing_km, handles)
    if extent_km is not None:
        ax.set_xlim(extent_km[0], extent_km[1])
        ax.set_ylim(extent_km[2], extent_km[3])
    else:
        ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("East [km]")
    ax.set_ylabel("North [km]")
    window = f", t = {time_window[0]:g}..{time_window[1]:g} s" if time_window else ""
    ax.set_title(title or f"Plan view: {n_plots} plots, {n_tracks} tracks{window}")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.85)
    if footnote:
        fig.text(0.01, 0.002, " | ".join(footnote), fontsize=7, color="0.3", ha="left", va="bottom")
    return fig


def _draw_radars(ax, radars: list[Sensor], ring_spacing_km: float | None, handles: list) -> None:
    if not radars:
        return
    max_ranges = [s.max_range_m / _KM for s in radars if s.max_range_m]
    reach = max(max_ranges) if max_ranges else None
    spacing = ring_spacing_km or (_nice_step(reach) if reach else None)
    for index, sensor in enumerate(radars):
        cx, cy = sensor.position[0] / _KM, sensor.position[1] / _KM
        ax.plot([cx], [cy], marker="^", ms=9, color="k", mec="white", zorder=5)
        ax.annotate(sensor.name, (cx, cy), xytext=(6, -10), textcoords="offset points", fontsize=8, zorder=6)
        limit = (sensor.max_range_m / _KM) if sensor.max_range_m else None
        if spacing is None or limit is None:
            continue
        for ring in np.arange(spacing, limit + 1e-9, spacing):
            ax.add_patch(Circle((cx, cy), ring, fill=False, lw=0.5, ls="--", color="0.5", zorder=0))
            if index == 0:
                ax.annotate(f"{ring:g} km", (cx, cy + ring), fontsize=7, color="0.4", ha="center", va="bottom")
        ax.update_datalim([(cx - limit, cy - limit), (cx + limit, cy + limit)])
    label = "radar" + (f", range rings every {spacing:g} km" if spacing else "")
    handles.append(Line2D([], [], ls="", marker="^", ms=8, color="k", label=label))


def plot_metrics_over_time(evaluation, path: str | Path, *, title: str | None = None, figsize=(10.0, 9.0), dpi: int = 150) -> Path:
    """OSPA, GOSPA split into localisation / missed / false (stacked), and counts over time.

    The GOSPA stack divides each instant's GOSPA in proportion to the terms of
    ``GOSPA^p = loc + c^p/2 missed + c^p/2 false``, so the stack's top is GOSPA itself.
    """
    path = Path(path)
    series = evaluation.series
    cutoff = float(evaluation.parameters["cutoff_m"])
    order = float(evaluation.parameters["order"])
    t = series["time"].to_numpy(dtype=float)
    span = float(t[-1] - t[0]) if t.size else 0.0
    t_scale, t_unit = (60.0, "min") if span > 600.0 else (1.0, "s")
    d_scale, d_unit = (_KM, "km") if cutoff >= _KM else (1.0, "m")
    tt = t / t_scale
    fig = Figure(figsize=figsize, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax_ospa, ax_gospa, ax_count = fig.subplots(3, 1, sharex=True, height_ratios=[1.0, 1.2, 0.8])

    ax_ospa.plot(tt, series["ospa_m"] / d_scale, color="C0", lw=1.4, label=f"OSPA (mean {evaluation.summary['ospa_mean_m'] / d_scale:.3g} {d_unit})")
    ax_ospa.plot(tt, series["position_rmse_m"] / d_scale, color="C3", lw=1.0, ls="--", label="position RMSE of assigned tracks")
    ax_ospa.axhline(cutoff / d_scale, color="0.5", lw=0.8, ls=":", label=f"cutoff c = {cutoff / d_scale:g} {d_unit}")
    ax_ospa.set_ylabel(f"distance [{d_unit}]")
    ax_ospa.set_title(f"OSPA (c = {cutoff:g} m, p = {order:g})")
    ax_ospa.legend(fontsize=8, loc="upper right")

    cp2 = 0.5 * cutoff**order
    parts = np.vstack([series["gospa_localisation"], cp2 * series["gospa_missed"], cp2 * series["gospa_false"]]).astype(float)
    total = parts.sum(axis=0)
    gospa = series["gospa_m"].to_numpy(dtype=float) / d_scale
    with np.errstate(invalid="ignore", divide="ignore"):
        shares = np.where(total > 0, parts / total * gospa, 0.0)
    ax_gospa.stackplot(tt, shares, colors=["C2", "C1", "C3"], alpha=0.75,
                       labels=["localisation", "missed truths", "false tracks"])
    ax_gospa.plot(tt, gospa, color="k", lw=1.0, label=f"GOSPA (mean {evaluation.summary['gospa_mean_m'] / d_scale:.3g} {d_unit})")
    ax_gospa.set_ylabel(f"GOSPA [{d_unit}]")
    ax_gospa.set_title(f"GOSPA (α = 2, c = {cutoff:g} m, p = {order:g}), split in proportion to its p-th power terms")
    ax_gospa.legend(fontsize=8, loc="upper right")

    ax_count.step(tt, series["n_truth_visible"], where="mid", color="0.2", label="visible truth objects")
    ax_count.step(tt, series["n_tracks"], where="mid", color="C0", label="confirmed tracks")
    ax_count.step(tt, series["n_assigned"], where="mid", color="C2", ls="--", label="assigned pairs")
    ax_count.set_ylabel("count")
    ax_count.set_xlabel(f"time since epoch [{t_unit}]")
    ax_count.legend(fontsize=8, loc="upper right")
    for ax in (ax_ospa, ax_gospa, ax_count):
        ax.grid(True, lw=0.3, alpha=0.5)
    fig.suptitle(title or f"Track quality over time: {evaluation.dimension} evaluation")
    fig.savefig(path)
    return path
