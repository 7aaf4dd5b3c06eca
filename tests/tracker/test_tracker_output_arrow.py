"""The Arrow way out of the tracker (Tracker.drain_arrow -> TrackWriter) writes exactly what
the DataFrame way (Tracker.drain -> TrackWriter) writes (skytrack.tracker.output)."""

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from skytrack.core.plots import (
    decode_icao24,
    decode_iff,
    decode_mode3a,
    icao24_text,
    iff_text,
    mode3a_text,
)
from skytrack.io import InputError
from skytrack.io.tracks import TrackWriter
from skytrack.tracker.config import TrackerConfig
from skytrack.tracker.tracker import Tracker


@pytest.fixture
def identified_plots(sim, radar1):
    rng = np.random.default_rng(5)
    targets = sim.ring_targets(rng, 6)
    plots = sim.merge_plots([sim.radar_plots(radar1, targets, 0.0, 120.0, rng, p_detection=0.9),
                             sim.isolated_clutter(radar1, 0.0, 120.0, 2, rng)])
    number = plots["truth_id"].str.removeprefix("t").replace("", "-1").astype(int).to_numpy()
    known = number >= 0
    # some targets squawk, some have a Mode S address, some answer IFF; clutter has nothing
    plots["mode3a"] = pd.array(np.where(known & (number % 2 == 0), [f"{1200 + n:04o}" for n in number], None),
                               dtype="str")
    plots["mode_s"] = pd.array(np.where(known & (number < 4), [f"{0x3C0000 + n:06x}" for n in number], None),
                               dtype="str")
    plots["iff"] = pd.array(np.where(known, np.array(["friend", "foe", "undetermined"])[number % 3], None),
                            dtype="str")
    return plots


def drained_both_ways(sensors, plots, config, cuts):
    """The tracks of ``plots`` fed in pieces, drained as DataFrames by one tracker and as
    Arrow tables by another."""
    frames, tables = [], []
    by_frame, by_arrow = Tracker(sensors, config), Tracker(sensors, config)
    for rows in np.split(np.arange(len(plots)), cuts):
        for tracker in (by_frame, by_arrow):
            tracker.feed(plots.iloc[rows])
        frames.append(by_frame.drain())
        tables.append(by_arrow.drain_arrow())
    for tracker in (by_frame, by_arrow):
        tracker.finish()
    frames.append(by_frame.drain())
    tables.append(by_arrow.drain_arrow())
    return frames, tables


def write_all(path, chunks):
    with TrackWriter(path) as writer:
        for chunk in chunks:
            writer.write(chunk, checked=True)
    return writer.rows


@pytest.mark.parametrize("full_covariance", [False, True])
@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_drain_arrow_writes_what_drain_writes(sim, radar1, identified_plots, tmp_path, full_covariance, suffix):
    config = TrackerConfig(full_covariance=full_covariance)
    frames, tables = drained_both_ways(sim.sensor_set([radar1]), identified_plots, config, [60, 61, 62, 150])
    assert any(t is None for t in tables) and sum(len(f) for f in frames) > 100
    rows_frame = write_all(tmp_path / f"frame{suffix}", frames)
    rows_arrow = write_all(tmp_path / f"arrow{suffix}", tables)
    assert rows_frame == rows_arrow == sum(len(f) for f in frames)
    if suffix == ".csv":
        assert (tmp_path / "arrow.csv").read_bytes() == (tmp_path / "frame.csv").read_bytes()
    else:
        written = pq.read_table(tmp_path / "arrow.parquet")
        assert written.equals(pq.read_table(tmp_path / "frame.parquet"))
        assert written["mode3a"].null_count < len(written) and written["icao24"].null_count < len(written)


def test_drain_arrow_of_a_3d_radar_writes_what_drain_writes(sim, tmp_path):
    radar = sim.Radar("r3d", sim.ORIGIN.lat, sim.ORIGIN.lon, 0.0, period=4.0, phase=0.0, sigma_range_m=40.0,
                      sigma_azimuth_deg=0.07, sigma_elevation_deg=0.1, type="radar-3d")
    rng = np.random.default_rng(8)
    plots = sim.radar_plots(radar, sim.ring_targets(rng, 5), 0.0, 80.0, rng, elevation=True)
    frames, tables = drained_both_ways(sim.sensor_set([radar]), plots, TrackerConfig(), [150])
    write_all(tmp_path / "frame.parquet", frames)
    write_all(tmp_path / "arrow.parquet", tables)
    written = pq.read_table(tmp_path / "arrow.parquet")
    assert written["z"].null_count == 0 and len(written) > 50
    assert written.equals(pq.read_table(tmp_path / "frame.parquet"))


def test_unchecked_arrow_tables_are_validated_like_frames(tmp_path):
    table = pa.table({"time": [0.0, 1.0], "track_id": [1, 1], "x": [0.0, 1.0], "y": [0.0, -1.0],
                      "var_x": [1.0, -4.0]})
    with TrackWriter(tmp_path / "t.parquet") as writer, pytest.raises(InputError) as from_arrow:
        writer.write(table)
    with TrackWriter(tmp_path / "u.parquet") as writer, pytest.raises(InputError) as from_frame:
        writer.write(table.to_pandas())
    assert str(from_arrow.value) == str(from_frame.value).replace("u.parquet", "t.parquet")
    assert "var_x" in str(from_arrow.value) and "is negative" in str(from_arrow.value)


def test_checked_arrow_table_gets_the_missing_columns_in_order(tmp_path):
    table = pa.table({"cov_0_0": [2.0], "y": [5.0], "x": [4.0], "track_id": [7], "time": [1.5]})
    with TrackWriter(tmp_path / "a.parquet") as writer:
        writer.write(table, checked=True)
    with TrackWriter(tmp_path / "f.parquet") as writer:
        writer.write(table.to_pandas())
    written = pq.read_table(tmp_path / "a.parquet")
    assert written.column_names[:4] == ["time", "track_id", "x", "y"] and written.column_names[-1] == "cov_0_0"
    assert written.equals(pq.read_table(tmp_path / "f.parquet"))


def test_identity_text_as_arrow_is_the_pandas_text():
    codes = np.array([-1, 0o1200, 0o7777, 0o1200, 0, -1], dtype=np.int32)
    for as_arrow, as_pandas in ((mode3a_text, decode_mode3a), (icao24_text, decode_icao24)):
        text = as_arrow(codes)
        assert text.type.value_type == pa.string() and text.dictionary.null_count == 0
        pd.testing.assert_extension_array_equal(pd.array(text.dictionary_decode(), dtype="str"), as_pandas(codes))
    iff = np.array([2, -1, 0, 1], dtype=np.int8)
    assert iff_text(iff).to_pylist() == ["undetermined", None, "friend", "foe"]
    assert sorted(iff_text(iff).dictionary.to_pylist()) == ["foe", "friend", "undetermined"]
    assert list(decode_iff(iff).fillna("-")) == ["undetermined", "-", "friend", "foe"]
    assert mode3a_text(codes).to_pylist() == [None, "1200", "7777", "1200", "0000", None]
