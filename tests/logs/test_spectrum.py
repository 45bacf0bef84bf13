"""Welch power spectral density of a stored series (logs/spectrum.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from logs.spectrum import SpectrumError, hann, spectrum, welch
from logs.store import import_to_store, open_store
from logs.synth import write_ulog

FS = 400.0


@pytest.fixture
def store(tmp_path):
    """60 s of a 400 Hz accelerometer axis: a 40 Hz tone of amplitude 2 for the first
    30 s, 90 Hz of amplitude 1 for the rest, on white noise."""
    n = int(60 * FS)
    t = np.arange(n) / FS
    rng = np.random.default_rng(4)
    x = np.where(t < 30, 2 * np.sin(2 * np.pi * 40 * t), np.sin(2 * np.pi * 90 * t))
    arr = np.zeros(n, dtype=[("timestamp", "<u8"), ("accel", "<f4"), ("text_id", "u1")])
    arr["timestamp"] = np.round(t * 1e6).astype(np.uint64)
    arr["accel"] = x + rng.normal(0, 0.1, n)
    write_ulog(tmp_path / "tone.ulg", {"imu": arr})
    return import_to_store(tmp_path / "tone.ulg", tmp_path / "store")


def test_the_peak_is_at_the_tone(store):
    first = spectrum(store, "imu/accel", start=0, end=29.9, nperseg=512)
    assert first.fs == pytest.approx(FS, rel=1e-6)
    assert first.frequency[np.argmax(first.psd)] == pytest.approx(40, abs=FS / 512)
    second = spectrum(store, "imu/accel", start=31, end=None, nperseg=512)
    assert second.frequency[np.argmax(second.psd)] == pytest.approx(90, abs=FS / 512)


def test_the_density_integrates_to_the_variance(store):
    """Parseval: a density (unit²/Hz) summed over frequency gives the signal's power,
    A²/2 for the tone plus the noise's variance."""
    s = spectrum(store, "imu/accel", start=0, end=29.9, nperseg=1024)
    df = s.frequency[1] - s.frequency[0]
    assert float(np.sum(s.psd) * df) == pytest.approx(2**2 / 2 + 0.1**2, rel=0.03)


def test_welch_matches_the_textbook_estimate_on_one_segment():
    """One segment: the periodogram of the windowed, mean-removed samples, scaled by
    fs * sum(w²), doubled except at 0 and Nyquist."""
    x = np.random.default_rng(3).normal(size=64)
    freq, psd = welch(x[None, :], 100.0)
    w = hann(64)
    expected = np.abs(np.fft.rfft((x - x.mean()) * w)) ** 2 / (100.0 * np.sum(w**2))
    expected[1:-1] *= 2
    np.testing.assert_allclose(psd, expected, rtol=1e-12)
    assert freq[-1] == 50.0


def test_cost_is_capped_by_the_segments_read(store):
    whole = spectrum(store, "imu/accel", nperseg=256)
    assert whole.segments == whole.segments_available == (24000 - 256) // 128 + 1
    capped = spectrum(store, "imu/accel", nperseg=256, max_segments=20)
    assert capped.segments == 20 and capped.segments_available == whole.segments_available
    # The capped estimate still sees both tones, spread over the whole flight.
    floor = float(np.median(capped.psd))
    for tone in (40, 90):
        near = np.abs(capped.frequency - tone) < 2
        assert capped.psd[near].max() > 100 * floor


def test_bad_requests_are_refused(store):
    with pytest.raises(SpectrumError, match="nperseg"):
        spectrum(store, "imu/accel", nperseg=8)
    with pytest.raises(SpectrumError, match="at least 256"):
        spectrum(store, "imu/accel", start=10, end=10.1, nperseg=256)
    with pytest.raises(SpectrumError, match="at least 16"):
        spectrum(store, "imu/accel", start=10, end=10.02)


def test_a_short_window_gets_shorter_segments(store):
    short = spectrum(store, "imu/accel", start=10, end=10.5)  # 201 samples
    assert short.nperseg == 128 and short.segments == 2
    with pytest.raises(KeyError):
        spectrum(store, "imu/nothing")


# Flight Review's acceleration PSD of PX4's sample log (scipy.signal.spectrogram, Hann,
# 256 samples, half overlap, density, averaged over time), computed with scipy 1.17:
# the power per axis (m/s²)² and the peak, for docs/log-checks.md's anchors.
FLIGHT_REVIEW_POWER = (0.0008237564088631188, 0.01054750282492023, 0.012926312592753675)
FLIGHT_REVIEW_PEAK_HZ = 19.53125


def test_the_acceleration_psd_of_px4s_sample_log_equals_flight_reviews(tmp_path):
    sample = Path(__file__).resolve().parents[1] / "data" / "ulog" / "sample_appended_multiple.ulg"
    import_to_store(sample, tmp_path / "store")
    store = open_store(tmp_path / "store")
    for axis, power in enumerate(FLIGHT_REVIEW_POWER):
        found = spectrum(store, f"sensor_combined/accelerometer_m_s2[{axis}]", nperseg=256)
        assert found.segments == 17 and found.fs == pytest.approx(250.0)
        df = found.frequency[1] - found.frequency[0]
        assert float(np.sum(found.psd) * df) == pytest.approx(power, rel=1e-4)
        assert found.frequency[np.argmax(found.psd[1:]) + 1] == FLIGHT_REVIEW_PEAK_HZ
