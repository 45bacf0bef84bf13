import numpy as np
import pytest

from logs.lod import downsample


def _hour_at_50hz():
    n = 3600 * 50
    t = np.arange(n, dtype=np.int64) * 20_000_000
    v = np.sin(np.arange(n) / 700.0) + np.random.default_rng(5).normal(size=n) * 0.05
    return t, v


def test_hour_long_50hz_series_fits_a_1500_pixel_plot_in_3000_points():
    t, v = _hour_at_50hz()
    small_t, small_v = downsample(t, v, 1500)
    assert 1500 <= len(small_t) <= 3000


def test_minmax_keeps_the_extremes_in_time_order():
    t, v = _hour_at_50hz()
    v[12345] = 40.0  # a one-sample spike must survive
    v[99999] = -40.0
    small_t, small_v = downsample(t, v, 1500)
    assert small_v.max() == 40.0 and small_v.min() == -40.0
    assert np.all(np.diff(small_t) > 0)
    # Every bucket's own min and max are there, not just the global ones.
    buckets = np.array_split(np.arange(len(v)), 1500)
    kept = set(small_t.tolist())
    for chunk in buckets[::97]:
        assert t[chunk[np.argmax(v[chunk])]] in kept or v[chunk].max() in small_v


def test_lttb_returns_exactly_the_requested_points_with_the_ends():
    t, v = _hour_at_50hz()
    small_t, small_v = downsample(t, v, 1500, method="lttb")
    assert len(small_t) == 1500
    assert small_t[0] == t[0] and small_t[-1] == t[-1]
    assert np.all(np.diff(small_t) > 0)
    assert small_v.max() > 0.95 and small_v.min() < -0.95


def test_short_series_come_back_unchanged():
    t = np.arange(10, dtype=np.int64)
    v = np.arange(10.0)
    small_t, small_v = downsample(t, v, 1500)
    np.testing.assert_array_equal(small_t, t)
    np.testing.assert_array_equal(small_v, v)


def test_nan_values_are_dropped_and_integers_are_kept_exact():
    t = np.arange(10_000, dtype=np.int64)
    v = np.arange(10_000, dtype=np.int64) % 7
    small_t, small_v = downsample(t, v, 100)
    assert small_v.dtype == np.int64 and set(small_v.tolist()) == {0, 6}
    f = np.where(np.arange(10_000) % 2 == 0, np.nan, 1.0)
    _, fv = downsample(t, f, 100)
    assert not np.isnan(fv).any()


def test_zero_points_is_refused():
    with pytest.raises(ValueError):
        downsample(np.arange(3), np.arange(3.0), 0)
