"""Benchmark: evaluate() on n_truth truths x n_steps output instants (not a unit test)."""
import time
import numpy as np, pandas as pd
from skytrack.analysis.evaluate import evaluate

def scenario(n_truth=1000, n_steps=150, dt=4.0, truth_dt=1.0, n_false=100, seed=1):
    rng = np.random.default_rng(seed)
    t_truth = np.arange(0, (n_steps - 1) * dt + truth_dt / 2, truth_dt)
    p0 = rng.uniform(-250e3, 250e3, (n_truth, 2)); z0 = rng.uniform(1e3, 12e3, n_truth)
    v = rng.normal(0, 150, (n_truth, 2))
    T = t_truth[None, :]
    truth = pd.DataFrame({
        "time": np.tile(t_truth, n_truth),
        "target_id": np.repeat([f"{i:06x}" for i in range(n_truth)], t_truth.size),
        "segment": 0,
        "x": (p0[:, :1] + v[:, :1] * T).ravel(), "y": (p0[:, 1:] + v[:, 1:] * T).ravel(),
        "z": np.repeat(z0, t_truth.size),
        "vx": np.repeat(v[:, 0], t_truth.size), "vy": np.repeat(v[:, 1], t_truth.size), "vz": 0.0,
        "visible": True,
    })
    t_out = np.arange(n_steps) * dt
    k = (t_out / truth_dt).round().astype(int)
    sel = (np.arange(n_truth)[:, None] * t_truth.size + k[None, :]).ravel()
    tr = truth.iloc[sel].reset_index(drop=True)
    n = len(tr)
    tracks = pd.DataFrame({
        "time": tr["time"].to_numpy(), "track_id": np.repeat(np.arange(n_truth), n_steps),
        "x": tr["x"].to_numpy() + rng.normal(0, 100, n), "y": tr["y"].to_numpy() + rng.normal(0, 100, n),
        "z": tr["z"].to_numpy() + rng.normal(0, 100, n),
        "vx": tr["vx"].to_numpy() + rng.normal(0, 5, n), "vy": tr["vy"].to_numpy() + rng.normal(0, 5, n),
        "vz": rng.normal(0, 5, n),
        "var_x": 1e4, "var_y": 1e4, "var_z": 1e4, "var_vx": 25.0, "var_vy": 25.0, "var_vz": 25.0,
        "status": "confirmed",
    })
    fs = rng.integers(0, n_steps, n_false)
    false = pd.DataFrame({"time": t_out[fs], "track_id": 10_000_000 + np.arange(n_false),
                          "x": rng.uniform(-250e3, 250e3, n_false), "y": rng.uniform(-250e3, 250e3, n_false),
                          "z": 5000.0, "vx": 0.0, "vy": 0.0, "vz": 0.0, "var_x": 1e4, "var_y": 1e4, "var_z": 1e4,
                          "var_vx": 25.0, "var_vy": 25.0, "var_vz": 25.0, "status": "confirmed"})
    return pd.concat([tracks, false], ignore_index=True), truth

if __name__ == "__main__":
    tracks, truth = scenario()
    print(f"truth rows {len(truth)}, track rows {len(tracks)}")
    for i in range(3):
        t0 = time.perf_counter(); ev = evaluate(tracks, truth); t1 = time.perf_counter()
        print(f"evaluate: {t1 - t0:.2f} s")
    d = ev.to_dict(per_target=False)
    print({k: d[k] for k in ("position_rmse_m", "velocity_rmse_mps", "n_false_tracks", "ospa_mean_m", "gospa_mean_m", "continuity_mean")}, d["nees"]["mean"])
