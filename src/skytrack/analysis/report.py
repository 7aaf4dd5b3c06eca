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

The PPI is an identified air picture when the tracks carry identities (``icao24``,
``callsign``: filled by ``skytrack track --adsb``, issue 9 item 7, spec 001 R13): every track
identified at its last row is labelled there with its callsign (its address when it has no
callsign), in a small font at the end of a thin leader, the leaders pointing away so that
labels do not cover each other (:func:`place_labels`); unidentified tracks keep the track-id
labels of the longest tracks.
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
    return _keyed_lines(frame, keys)[1]


def _keyed_lines(frame: pd.DataFrame | None, keys: list[str]) -> tuple[list, list[np.ndarray]]:
    """The groups of ``keys`` with at least two rows (in sorted order) and their polylines in km."""
    if frame is None or len(frame) == 0:
        return [], []
    ordered = frame.sort_values([*keys, "time"], kind="stable")
    xy = ordered[["x", "y"]].to_numpy(dtype=float) / _KM
    group = ordered.groupby(keys, sort=False).ngroup().to_numpy()
    cuts = np.flatnonzero(np.diff(group)) + 1
    first_rows = np.r_[0, cuts]
    names = ordered[keys[0]].to_numpy()[first_rows] if len(keys) == 1 else \
        list(ordered[keys].iloc[first_rows].itertuples(index=False, name=None))
    kept = [(name, line) for name, line in zip(names, np.split(xy, cuts)) if len(line) >= 2]
    return [name for name, _ in kept], [line for _, line in kept]


def track_identities(tracks: pd.DataFrame) -> pd.DataFrame:
    """Per track: ``x, y`` of its last row and the ``label`` it carries there (callsign, else
    icao24, else null), indexed by ``track_id``.  A track that lost its label keeps none: the
    picture shows the identity the track has now, not one it had."""
    # the last row itself (groupby().last() would take each column's last non-null value)
    last = tracks.sort_values(["track_id", "time"], kind="stable").drop_duplicates("track_id", keep="last")
    last = last.set_index("track_id")
    label = np.full(len(last), None, dtype=object)
    for column in ("icao24", "callsign"):  # the callsign, when there is one, wins
        if column in last.columns:
            text = last[column].astype("string").str.strip()
            given = (text.notna() & (text != "")).to_numpy()
            label[given] = text.to_numpy(dtype=object)[given]
    return pd.DataFrame({"x": last["x"].to_numpy(float), "y": last["y"].to_numpy(float),
                         "label": pd.Series(label, index=last.index, dtype=object)}, index=last.index)


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
    take 60 distinct colour and dash styles.  Tracks identified at their last row carry their
    callsign (or address) there; the ``n_track_labels`` longest of the others their id."""
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
    labels: list[tuple] = []
    if tracks_df is not None and len(tracks_df):
        line_ids, lines = _keyed_lines(tracks_df, ["track_id"])
        n_tracks = tracks_df["track_id"].nunique()
        styles = track_styles(len(lines))
        colour_of = {track_id: colour for track_id, (colour, _) in zip(line_ids, styles)}
        ax.add_collection(LineCollection(lines, colors=[c for c, _ in styles], linestyles=[d for _, d in styles],
                                         linewidths=TRACK_WIDTH, zorder=4, label="tracks"))
        identities = track_identities(tracks_df)
        identified = identities[identities["label"].notna()]
        lengths = tracks_df.groupby("track_id").size().sort_values(ascending=False, kind="stable")
        with_id = [t for t in lengths.index if t not in identified.index][:n_track_labels]
        handles.append(Line2D([], [], color=TRACK_COLOURS[0], lw=TRACK_WIDTH,
                              label=f"tracks ({n_tracks}, {min(n_tracks, 60)} styles; ids on the "
                                    f"{len(with_id)} longest unidentified)"))
        if len(identified):
            handles.append(Line2D([], [], color="0.15", lw=LEADER_WIDTH,
                                  label=f"callsign (else address) of the {len(identified)} identified tracks, "
                                        "at their last position"))
        # callsigns first: they win the free places around their tracks
        labels = [(str(label), x / _KM, y / _KM, colour_of.get(track_id, "0.3"), CALLSIGN_FONT, "0.05")
                  for track_id, (x, y, label) in identified.iterrows()]
        labels += [(str(track_id), identities.at[track_id, "x"] / _KM, identities.at[track_id, "y"] / _KM,
                    colour_of.get(track_id, "0.3"), TRACK_ID_FONT, "0.3") for track_id in with_id]
    radars = [s for s in by_name.values() if s.is_radar]
    _draw_radars(ax, radars, ring_spacing_km, handles)
    if extent_km is not None:
        ax.set_xlim(extent_km[0], extent_km[1])
        ax.set_ylim(extent_km[2], extent_km[3])
    else:
        ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    if labels:
        _draw_labels(ax, labels)
    ax.set_xlabel("East [km]")
    ax.set_ylabel("North [km]")
    window = f", t = {time_window[0]:g}..{time_window[1]:g} s" if time_window else ""
    ax.set_title(title or f"Plan view: {n_plots} plots, {n_tracks} tracks{window}")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.85)
    if footnote:
        fig.text(0.01, 0.002, " | ".join(footnote), fontsize=7, color="0.3", ha="left", va="bottom")
    return fig


#: label fonts (points) and the leader line from a track's last position to its label
CALLSIGN_FONT = 6.0
TRACK_ID_FONT = 6.5
LEADER_WIDTH = 0.5
#: where a label may go, in points from its anchor: 8 directions on growing rings
_LABEL_RADII = (9.0, 16.0, 26.0, 40.0)
_LABEL_DIRECTIONS = ((1, 1), (-1, 1), (1, -1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1))


def place_labels(anchors: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """Greedy placement of text boxes around anchor points, all in points on the page.

    ``anchors [N, 2]`` are the points labelled, ``sizes [N, 2]`` the boxes' width and height.
    Each box in turn takes the first offset (8 directions on rings of growing radius, the box
    on the far side of its leader's end) that overlaps neither a box already placed nor an
    anchor; when none is free, the one with the least overlap.  Returns the offsets ``[N, 2]``
    of the leaders' ends (the boxes extend away from the anchor from there)."""
    directions = np.array(_LABEL_DIRECTIONS, dtype=float)
    unit = directions / np.linalg.norm(directions, axis=1)[:, None]
    offsets = np.concatenate([radius * unit for radius in _LABEL_RADII])
    signs = np.tile(directions, (len(_LABEL_RADII), 1))
    placed = np.empty((0, 4))  # x0, y0, x1, y1 of boxes placed
    dot = 1.5
    points = np.column_stack([anchors - dot, anchors + dot]) if len(anchors) else np.empty((0, 4))
    chosen = np.zeros((len(anchors), 2))
    for k, (anchor, (width, height)) in enumerate(zip(anchors, sizes)):
        corner = anchor + offsets
        # the box sits right of / above its leader's end for positive signs, centred for zero
        x0 = corner[:, 0] - np.where(signs[:, 0] > 0, 0.0, np.where(signs[:, 0] < 0, width, width / 2))
        y0 = corner[:, 1] - np.where(signs[:, 1] > 0, 0.0, np.where(signs[:, 1] < 0, height, height / 2))
        boxes = np.column_stack([x0, y0, x0 + width, y0 + height])
        others = np.concatenate([placed, np.delete(points, k, axis=0)])
        overlap = _overlap_area(boxes, others)
        best = int(np.argmax(overlap == 0.0)) if (overlap == 0.0).any() else int(np.argmin(overlap))
        chosen[k] = offsets[best]
        placed = np.vstack([placed, boxes[best]])
    return chosen


def _overlap_area(boxes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Total overlap area of each of ``boxes [M, 4]`` with ``others [K, 4]``."""
    if len(others) == 0:
        return np.zeros(len(boxes))
    width = np.minimum(boxes[:, None, 2], others[None, :, 2]) - np.maximum(boxes[:, None, 0], others[None, :, 0])
    height = np.minimum(boxes[:, None, 3], others[None, :, 3]) - np.maximum(boxes[:, None, 1], others[None, :, 1])
    return (np.clip(width, 0, None) * np.clip(height, 0, None)).sum(axis=1)


def _draw_labels(ax, labels: list[tuple]) -> None:
    """``(text, x_km, y_km, track colour, font size, text colour)`` as annotations with leaders."""
    ax.apply_aspect()  # the final limits, so that km convert to points as they will be drawn
    fig = ax.figure
    box = ax.get_position()
    width_pt, height_pt = box.width * fig.get_figwidth() * 72.0, box.height * fig.get_figheight() * 72.0
    (x_lo, x_hi), (y_lo, y_hi) = ax.get_xlim(), ax.get_ylim()
    xy = np.array([(x, y) for _, x, y, *_ in labels], dtype=float)
    anchors = np.column_stack([(xy[:, 0] - x_lo) / (x_hi - x_lo) * width_pt, (xy[:, 1] - y_lo) / (y_hi - y_lo) * height_pt])
    pad = 2.0
    sizes = np.array([(0.62 * size * len(text) + 2 * pad, 1.25 * size + 2 * pad) for text, _, _, _, size, _ in labels])
    offsets = place_labels(anchors, sizes)
    for (text, x, y, colour, size, text_colour), (dx, dy) in zip(labels, offsets):
        ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset points", fontsize=size, color=text_colour,
                    ha="left" if dx > 0.5 else "right" if dx < -0.5 else "center",
                    va="bottom" if dy > 0.5 else "top" if dy < -0.5 else "center", zorder=7,
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.75),
                    arrowprops=dict(arrowstyle="-", lw=LEADER_WIDTH, color=colour, shrinkA=0.0, shrinkB=0.0))


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
