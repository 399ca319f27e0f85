"""Range noise and dropouts: statistics, reproducibility, batching, required generator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from platoon_sumo.sensors import LaserConfig, apply_noise, cast_rays, scan_many

WALL = [[5.0, -100.0, 5.0, 100.0]]


def noisy(std: float = 0.05, drop: float = 0.1) -> LaserConfig:
    return LaserConfig(-0.5, 0.5, 1081, 0.1, 30.0, noise_std_m=std, dropout_prob=drop)


def test_noise_mean_std_and_dropout_fraction_match_parameters() -> None:
    config = noisy()
    rng = np.random.default_rng(123)
    truth = cast_rays([0, 0], 0.0, LaserConfig(-0.5, 0.5, 1081, 0.1, 30.0), segments=WALL)
    scans = np.array([cast_rays([0, 0], 0.0, config, segments=WALL, rng=rng) for _ in range(40)])
    n = scans.size
    dropped = np.isnan(scans)
    p = config.dropout_prob
    assert abs(dropped.mean() - p) <= 5.0 * math.sqrt(p * (1 - p) / n)
    err = (scans - truth)[~dropped]
    m = err.size
    assert abs(err.mean()) <= 5.0 * config.noise_std_m / math.sqrt(m)
    # the standard deviation estimate has a standard error of about std / sqrt(2 m)
    assert abs(err.std(ddof=1) - config.noise_std_m) <= 5.0 * config.noise_std_m / math.sqrt(2 * m)


def test_same_seed_same_scan_and_batched_equals_sequential() -> None:
    config = noisy()
    origins = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, -2.0]])
    headings = np.array([0.0, 0.1, -0.2])
    a = scan_many(origins, headings, config, segments=WALL, rng=np.random.default_rng(5))
    b = scan_many(origins, headings, config, segments=WALL, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)  # NaNs compare equal here
    rng = np.random.default_rng(5)
    one_by_one = [
        cast_rays(o, h, config, segments=WALL, rng=rng)
        for o, h in zip(origins, headings, strict=True)
    ]
    np.testing.assert_array_equal(a, np.array(one_by_one))
    c = scan_many(origins, headings, config, segments=WALL, rng=np.random.default_rng(6))
    assert not np.array_equal(a, c)


def test_noisy_readings_stay_in_range_and_no_return_is_untouched() -> None:
    config = LaserConfig(-1.0, 1.0, 501, 0.3, 5.05, noise_std_m=0.5)
    ranges = cast_rays([0, 0], 0.0, config, segments=WALL, rng=np.random.default_rng(0))
    finite = ranges[np.isfinite(ranges)]
    assert finite.size > 0
    assert finite.min() >= 0.3 and finite.max() <= 5.05
    clean = cast_rays([0, 0], 0.0, LaserConfig(-1.0, 1.0, 501, 0.3, 5.05), segments=WALL)
    np.testing.assert_array_equal(np.isposinf(ranges), np.isposinf(clean))


@pytest.mark.parametrize("config", [noisy(0.01, 0.0), noisy(0.0, 0.2)])
def test_noise_or_dropout_without_generator_is_a_clear_error(config: LaserConfig) -> None:
    with pytest.raises(ValueError, match="rng"):
        cast_rays([0, 0], 0.0, config, segments=WALL)
    with pytest.raises(ValueError, match="rng"):
        scan_many([[0, 0]], [0.0], config, segments=WALL)


def test_noiseless_config_ignores_generator() -> None:
    config = LaserConfig(-0.5, 0.5, 11, 0.1, 30.0)
    rng = np.random.default_rng(1)
    state = rng.bit_generator.state
    cast_rays([0, 0], 0.0, config, segments=WALL, rng=rng)
    assert rng.bit_generator.state == state
    ranges = np.array([[1.0, np.inf]])
    assert apply_noise(ranges, LaserConfig(0.0, 1.0, 2, 0.1, 3.0), None) is ranges
