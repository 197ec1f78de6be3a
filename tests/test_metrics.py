"""Metric functions (tlac.experiments.metrics) against values computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from tlac.experiments import metrics as m


def test_window_and_initial_performance():
    t = [100, 250, 400, 900]
    r = [0.0, 1.0, 0.5, 0.2]
    # episodes ending at <= 300: 0.0 and 1.0 -> 0.5
    assert m.initial_performance(t, r, window=300) == pytest.approx(0.5)
    # the window's end is inclusive: <= 400 -> (0 + 1 + 0.5) / 3
    assert m.initial_performance(t, r, window=400) == pytest.approx(0.5)
    assert m.initial_performance(t, r, window=50) != m.initial_performance(t, r, window=50)  # NaN
    # (250, 900]: 0.5 and 0.2
    assert m.window_mean(t, r, 250, 900) == pytest.approx(0.35)


def test_final_performance_uses_last_window():
    t = [100, 500, 800, 950, 1000]
    r = [0.0, 0.0, 3.0, 4.0, 8.0]
    # last 250 of 1000 steps: (750, inf) -> 3, 4, 8 -> 5
    assert m.final_performance(t, r, total_steps=1000, window=250) == pytest.approx(5.0)


def test_jumpstart_against_hand_values():
    # advice runs: initial performance (first 1000 steps) 0.8 and 0.6 -> 0.7
    runs = [([200, 600, 1500], [0.7, 0.9, 0.0]), ([400, 2000], [0.6, 1.0])]
    # baseline: 0.1 and 0.0 (second one: mean(0, 0)) -> 0.05
    base = [([300, 3000], [0.1, 0.5]), ([500, 999], [0.0, 0.0])]
    assert m.jumpstart(runs, base, window=1000) == pytest.approx(0.7 - 0.05)
    # a run without an episode in the window is skipped, not counted as 0
    runs2 = [*runs, ([5000], [9.0])]
    assert m.jumpstart(runs2, base, window=1000) == pytest.approx(0.65)
    assert math.isnan(m.jumpstart([([5000], [1.0])], base, window=1000))


def test_binned_curve_carries_forward_and_starts_nan():
    grid = [10, 20, 30, 40]
    t = [12, 18, 19, 35, 41]
    r = [1.0, 2.0, 3.0, 10.0, 99.0]
    # (-inf,10]: none -> NaN; (10,20]: mean(1,2,3)=2; (20,30]: none -> 2; (30,40]: 10; 41 dropped
    out = m.binned_curve(t, r, grid)
    assert math.isnan(out[0])
    np.testing.assert_allclose(out[1:], [2.0, 2.0, 10.0])
    # an episode exactly on a grid point belongs to that point's bin
    np.testing.assert_allclose(m.binned_curve([10, 20], [1.0, 5.0], grid), [1.0, 5.0, 5.0, 5.0])


def test_step_grid():
    np.testing.assert_allclose(m.step_grid(1000, 4), [250, 500, 750, 1000])


def test_interpolated_curve():
    out = m.interpolated_curve([0, 100, 200], [0.0, 1.0, 3.0], [50, 150, 200, 250])
    np.testing.assert_allclose(out[:3], [0.5, 2.0, 3.0])
    assert math.isnan(out[3])


def test_mean_std_over_seeds_ignores_nan():
    curves = np.array([[1.0, 2.0, np.nan], [3.0, 6.0, np.nan], [np.nan, 4.0, np.nan]])
    mean, std = m.mean_std(curves)
    np.testing.assert_allclose(mean[:2], [2.0, 4.0])
    # population std: sqrt(((1-2)^2 + (3-2)^2) / 2) = 1; sqrt((4 + 4 + 0) / 3)
    np.testing.assert_allclose(std[:2], [1.0, math.sqrt(8 / 3)])
    assert math.isnan(mean[2]) and math.isnan(std[2])


def test_area_under_curve_trapezoid():
    # trapezoids: (0+2)/2*10 + (2+2)/2*10 + (2+6)/2*20 = 10 + 20 + 80 = 110
    grid, curve = [0, 10, 20, 40], [0.0, 2.0, 2.0, 6.0]
    assert m.area_under_curve(grid, curve) == pytest.approx(110.0)
    assert m.area_under_curve(grid, curve, normalize=True) == pytest.approx(110.0 / 40)
    # NaN points (before the first episode) are left out: (2+2)/2*10 + (2+6)/2*20 = 100
    assert m.area_under_curve(grid, [np.nan, 2.0, 2.0, 6.0]) == pytest.approx(100.0)


def test_time_to_threshold():
    grid = [100, 200, 300, 400]
    assert m.time_to_threshold(grid, [0.1, 0.5, 0.9, 0.7], 0.8) == 300.0
    assert m.time_to_threshold(grid, [np.nan, 0.5, 0.5, 0.5], 0.5) == 200.0
    assert math.isnan(m.time_to_threshold(grid, [0.1, 0.2, 0.3, 0.4], 0.8))


def test_iqm_hand_values():
    # n = 8: drop 2 from each end -> mean(3, 4, 100, 200) = 76.75
    assert m.iqm([400, 3, 1, 200, 2, 100, 4, 300]) == pytest.approx(76.75)
    # n = 5: floor(1.25) = 1 from each end -> mean(2, 3, 4) = 3
    assert m.iqm([5, 1, 4, 2, 3]) == pytest.approx(3.0)
    # n = 3: nothing trimmed
    assert m.iqm([1, 2, 10]) == pytest.approx(13 / 3)


def test_stratified_bootstrap_constant_task_and_reproducible():
    # every run of every task equal -> every replicate equal -> degenerate interval
    point, lo, hi = m.stratified_bootstrap_ci(np.full((4, 3), 2.5), reps=50, seed=1)
    assert (point, lo, hi) == (2.5, 2.5, 2.5)
    scores = np.array([[0.0, 10.0], [1.0, 11.0], [2.0, 12.0], [3.0, 13.0]])
    a = m.stratified_bootstrap_ci(scores, reps=300, seed=7)
    b = m.stratified_bootstrap_ci(scores, reps=300, seed=7)
    assert a == b  # fixed random state
    point, lo, hi = a
    # 8 scores, trim 2 from each end: mean(2, 3, 10, 11) = 6.5
    assert point == pytest.approx(6.5)
    assert lo <= point <= hi


def test_stratified_bootstrap_resamples_within_tasks():
    # Task A's runs are all 0, task B's all 100: a stratified resample always keeps 2 zeros and
    # 2 hundreds, so with statistic = mean every replicate is exactly 50. An unstratified
    # bootstrap over the 4 pooled scores would spread from 0 to 100.
    tasks = [np.array([0.0, 0.0]), np.array([100.0, 100.0])]
    point, lo, hi = m.stratified_bootstrap_ci(tasks, statistic=np.mean, reps=200, seed=0)
    assert (point, lo, hi) == (50.0, 50.0, 50.0)


def test_bootstrap_percentiles_of_a_single_task_follow_resampling():
    # one task, two runs {0, 1}, statistic = mean: each replicate is 0, 0.5 or 1 with
    # probabilities 1/4, 1/2, 1/4; the 2.5% and 97.5% percentiles are then 0 and 1.
    point, lo, hi = m.stratified_bootstrap_ci([0.0, 1.0], statistic=np.mean, reps=4000, seed=3)
    assert point == 0.5 and lo == 0.0 and hi == 1.0


def test_reuse_frequency_pools_windows_and_seeds():
    usage = pd.DataFrame(
        {
            "timestep": [1000, 1000, 2000, 2000, 1000, 1000, 1000],
            "region": ["left", "left", "left", "left", "left", "left", "right"],
            "choice": ["L", "agent", "L", "agent", "L", "agent", "agent"],
            "count": [3, 1, 1, 3, 2, 2, 5],
        }
    )
    out = m.reuse_frequency(usage, bin_width=2000)
    left = out[out.region == "left"].set_index("choice")
    # one bin (0, 2000] for left: L = 3+1+2 = 6, agent = 1+3+2 = 6 -> 0.5 each
    assert list(left["step"].unique()) == [2000.0]
    assert left.loc["L", "fraction"] == pytest.approx(0.5)
    assert left.loc["agent", "count"] == 6
    right = out[out.region == "right"]
    assert right["fraction"].tolist() == [1.0]


def test_probability_of_improvement_hand_computed() -> None:
    # task 1: pairs (3>2, 3>1, 1<2, 1=1) -> (1 + 1 + 0 + 0.5) / 4 = 0.625 ; task 2: 2 > 1 -> 1
    x, y = [[3.0, 1.0], [2.0]], [[2.0, 1.0], [1.0]]
    assert m.probability_of_improvement(x, y) == pytest.approx((0.625 + 1.0) / 2)
    assert m.probability_of_improvement(y, x) == pytest.approx((0.375 + 0.0) / 2)
    assert m.probability_of_improvement([[1.0, 2.0]], [[1.0, 2.0]]) == pytest.approx(0.5)


def test_performance_profile_moving_average_and_bootstrap_band() -> None:
    assert m.performance_profile([0.2, 0.5, 0.9, 1.0], [0.0, 0.5, 0.95]).tolist() == [
        1.0,
        0.5,
        0.25,
    ]
    assert m.moving_average([0.0, 1.0, 2.0, np.nan, 4.0], 2).tolist() == [0.0, 0.5, 1.5, 2.0, 4.0]
    curves = np.array([[0.0, 1.0], [2.0, 3.0], [4.0, 5.0]])
    mean, lo, hi = m.bootstrap_mean_ci(curves, reps=4000, seed=1)
    assert mean.tolist() == [2.0, 3.0]
    # the bootstrap distribution of a mean of 3 draws from {0, 2, 4}: 2.5% / 97.5% quantiles
    assert lo[0] == pytest.approx(0.0, abs=0.7) and hi[0] == pytest.approx(4.0, abs=0.7)
    assert np.all(lo <= mean) and np.all(mean <= hi)
