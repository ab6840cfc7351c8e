"""Jerk and SPARC on analytic paths, and on a trained toy run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ndp.experiments.smoothness import mean_squared_jerk, path_smoothness, sparc


def min_jerk(t: np.ndarray, duration: float, amplitude: float) -> np.ndarray:
    s = t / duration
    return amplitude * (10 * s**3 - 15 * s**4 + 6 * s**5)


def test_jerk_of_the_minimum_jerk_curve_matches_the_analytic_value():
    # x = A (10 s^3 - 15 s^4 + 6 s^5), s = t / T: jerk = A / T^3 (60 - 360 s + 360 s^2), whose
    # mean square over [0, 1] is 720 A^2 / T^6
    dt, duration, amp = 1e-3, 1.5, 0.3
    t = np.arange(0, duration + dt / 2, dt)
    got = mean_squared_jerk(min_jerk(t, duration, amp), dt)
    assert got == pytest.approx(720 * amp**2 / duration**6, rel=1e-2)  # ends: 3 samples short


def test_noise_and_stop_and_go_are_less_smooth_by_both_measures():
    dt, duration = 0.0125, 2.0
    t = np.arange(0, duration + dt / 2, dt)
    clean = np.stack([min_jerk(t, duration, 0.3), min_jerk(t, duration, -0.1)], axis=1)
    rng = np.random.default_rng(0)
    noisy = clean + rng.normal(0, 2e-3, clean.shape)
    # five sub-movements, each from rest to rest (what a DMP started at rest per decision does)
    seg = np.concatenate([min_jerk(np.arange(0, 0.4, dt), 0.4, 0.06) + 0.06 * i for i in range(5)])
    stop_go = np.stack([seg, -seg / 3], axis=1)
    a, b, c = (path_smoothness(p, dt) for p in (clean, noisy, stop_go[: len(clean)]))
    assert b["jerk"] > 10 * a["jerk"] and c["jerk"] > a["jerk"]
    assert b["sparc"] < a["sparc"] and c["sparc"] < a["sparc"] < 0


def test_sparc_is_independent_of_amplitude_and_duration():
    dt = 1e-3
    v = lambda t, d, a: np.gradient(min_jerk(t, d, a), dt)  # noqa: E731
    t1, t2 = np.arange(0, 1.0, dt), np.arange(0, 2.0, dt)
    s1 = sparc(v(t1, 1.0, 0.2), dt)
    assert sparc(v(t1, 1.0, 5.0), dt) == pytest.approx(s1, rel=1e-9)
    assert sparc(v(t2, 2.0, 0.2), dt) == pytest.approx(s1, abs=0.05)
    assert sparc(np.zeros(50), dt) == 0.0


def test_bad_input():
    with pytest.raises(ValueError, match="at least 4"):
        mean_squared_jerk(np.zeros((3, 2)), 0.1)
    with pytest.raises(ValueError, match="dt"):
        mean_squared_jerk(np.zeros((5, 2)), 0.0)


def test_run_smoothness_of_a_trained_toy_run(tmp_path):
    from ndp.cli import main
    from ndp.experiments.smoothness import run_smoothness

    run = tmp_path / "r"
    assert main(["rl", "train", "--task", "point-mass", "--steps", "1040", "--vector", "sync",
                 "--run-dir", str(run), "--no-progress", "--no-tensorboard"]) == 0  # fmt: skip
    out = run_smoothness(run, episodes=2)
    assert out["episodes"] == 2 and np.isfinite(out["jerk"]) and out["sparc"] <= 0


def test_side_by_side_render_of_two_runs(tmp_path):
    from ndp.cli import main
    from ndp.rl.evaluate import render

    runs = []
    for algo in ("ndp", "ppo-multi"):
        run = tmp_path / algo
        assert main(["rl", "train", "--task", "point-mass", "--algo", algo, "--steps", "520",
                     "--steps-per-update", "512", "--vector", "sync", "--run-dir", str(run),
                     "--no-progress", "--no-tensorboard"]) == 0  # fmt: skip
        runs.append(run)
    out = render(runs[0], tmp_path / "both.mp4", compare=runs[1])
    assert out["frames"] > 10 and 0 <= out["success_any_compare"] <= 1
    import imageio.v3 as iio

    frame = iio.imread(tmp_path / "both.mp4", index=0)
    assert frame.shape[:2] == (96, 2 * 96 + 4)  # two 96-pixel views, a 4-pixel gap between
    small = render(runs[0], tmp_path / "small.mp4", compare=runs[1], width=64, height=48)
    assert (small["width"], small["height"]) == (64, 48)  # each run's frame
    assert iio.imread(tmp_path / "small.mp4", index=0).shape[:2] == (48, 2 * 64 + 4)


def test_smoothness_study_over_runs_caches_filters_and_writes_the_table(tmp_path, monkeypatch):
    import importlib.util
    import json

    from ndp.cli import main
    from ndp.experiments import smoothness

    runs = tmp_path / "runs"
    for algo in ("ndp", "ppo-multi"):
        assert main(["rl", "train", "--task", "point-mass", "--algo", algo, "--steps", "520",
                     "--steps-per-update", "512", "--vector", "sync",
                     "--run-dir", str(runs / f"point-mass-{algo}-s0"),
                     "--no-progress", "--no-tensorboard"]) == 0  # fmt: skip
    rows = smoothness.smoothness_of_runs([runs], episodes=2)
    assert [(r["task"], r["method"], r["seed"]) for r in rows] == [
        ("point-mass", "ndp", 0),
        ("point-mass", "ppo-multi", 0),
    ]
    cache = runs / "point-mass-ndp-s0" / "smoothness-e2-s10000.json"
    assert json.loads(cache.read_text())["jerk"] == rows[0]["jerk"]
    # a second pass reads the cache: no rollout happens
    monkeypatch.setattr(smoothness, "run_smoothness", lambda *a: pytest.fail("not cached"))
    again = smoothness.smoothness_of_runs([runs], episodes=2, methods=["ndp"])
    assert [r["method"] for r in again] == ["ndp"] and again[0]["jerk"] == rows[0]["jerk"]
    summary = smoothness.summarise([*rows, {**rows[0], "seed": 1, "jerk": 3 * rows[0]["jerk"]}])
    ndp_row = next(r for r in summary if r["method"] == "ndp")
    assert ndp_row["n_seeds"] == 2 and ndp_row["seeds"] == "0 1"
    assert ndp_row["jerk_mean"] == pytest.approx(2 * rows[0]["jerk"])
    with pytest.raises(ValueError, match="episodes"):
        smoothness.smoothness_of_runs([runs], episodes=0)

    spec = importlib.util.spec_from_file_location(
        "bench_smoothness", Path(__file__).parents[2] / "benchmarks" / "smoothness.py"
    )
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out = tmp_path / "res" / "smooth"
    assert bench.main([str(runs), "--episodes", "2", "--out", str(out)]) == 0
    md = out.with_suffix(".md").read_text()
    assert "| point-mass | ndp | 0 |" in md and "Commit:" in md
    assert out.with_suffix(".png").stat().st_size > 1000
    assert "ppo-multi" in out.with_suffix(".csv").read_text()
