"""Power spectral density of a stored series by Welch's method, in numpy alone.

Welch's estimate [Welch 1967]: the series is cut into segments of `nperseg` samples that
overlap by half, each has its mean removed and a periodic Hann window applied, and the
squared magnitudes of their FFTs are averaged; density scaling (unit²/Hz), one-sided.
With every segment used this is scipy.signal.welch's default estimate.

Cost is bounded whatever the log's length: at most `max_segments` segments are taken,
spread evenly over the window, and only their samples are read from the memory-mapped
store, so a request reads at most max_segments x nperseg values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from logs.store import NS, LogStore

DEFAULT_NPERSEG = 256
MIN_NPERSEG, MAX_NPERSEG = 16, 4096
DEFAULT_MAX_SEGMENTS = 256


class SpectrumError(ValueError):
    pass


@dataclass
class Spectrum:
    path: str
    unit: str
    fs: float  # Hz, from the median interval of the samples used
    nperseg: int
    segments: int  # averaged
    segments_available: int  # in the window, before the cap
    frequency: np.ndarray
    psd: np.ndarray

    def to_dict(self) -> dict:
        return {
            "path": self.path,
            "unit": f"({self.unit})²/Hz" if self.unit else "1/Hz",
            "fs": self.fs,
            "nperseg": self.nperseg,
            "segments": self.segments,
            "segments_available": self.segments_available,
            "frequency": self.frequency.tolist(),
            "psd": [x if math.isfinite(x) else None for x in self.psd.tolist()],
        }


def hann(n: int) -> np.ndarray:
    """The periodic Hann window (scipy.signal.get_window('hann', n))."""
    return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)


def welch(segments: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies, PSD) averaged over the rows of `segments` (k x nperseg)."""
    n = segments.shape[1]
    window = hann(n)
    x = segments - segments.mean(axis=1, keepdims=True)
    spectra = np.abs(np.fft.rfft(x * window, axis=1)) ** 2
    psd = spectra.mean(axis=0) / (fs * float(np.sum(window**2)))
    # One-sided: every bin but DC (and Nyquist for an even length) holds both halves.
    if n % 2 == 0:
        psd[1:-1] *= 2.0
    else:
        psd[1:] *= 2.0
    return np.fft.rfftfreq(n, d=1.0 / fs), psd


def spectrum(
    store: LogStore,
    path: str,
    *,
    start: float | None = None,
    end: float | None = None,
    nperseg: int | None = None,
    max_segments: int = DEFAULT_MAX_SEGMENTS,
) -> Spectrum:
    """The PSD of `path` between start and end (seconds on the log's clock, the whole
    log when None). Without `nperseg`, DEFAULT_NPERSEG samples a segment, fewer (a power
    of two) for a short window. Raises SpectrumError when the series is not numeric or
    too short."""
    if nperseg is not None and not MIN_NPERSEG <= nperseg <= MAX_NPERSEG:
        raise SpectrumError(f"nperseg must be between {MIN_NPERSEG} and {MAX_NPERSEG}.")
    info = store.info(path)
    if info["kind"] not in ("int", "double"):
        raise SpectrumError(f"{path} is not a numeric series.")
    t_all, v_all = store.read_ns(
        path,
        None if start is None else math.floor(start * NS),
        None if end is None else math.ceil(end * NS),
    )
    n = len(t_all)
    if nperseg is None:
        nperseg = DEFAULT_NPERSEG
        while nperseg > n and nperseg > MIN_NPERSEG:
            nperseg //= 2
    if n < nperseg:
        raise SpectrumError(
            f"{path} has {n} samples in this window; a spectrum needs at least {nperseg}."
        )
    step = nperseg // 2
    available = (n - nperseg) // step + 1
    count = min(available, max(1, int(max_segments)))
    # Evenly spread segment starts (all of them when under the cap).
    starts = np.unique(np.linspace(0, available - 1, count).round().astype(np.int64)) * step
    index = starts[:, None] + np.arange(nperseg)[None, :]
    times = np.asarray(t_all[index], dtype=np.int64)
    values = np.asarray(v_all[index], dtype=np.float64)
    intervals = np.diff(times, axis=1)
    positive = intervals[intervals > 0]
    if not len(positive):
        raise SpectrumError(f"{path} has no increasing time stamps in this window.")
    fs = NS / float(np.median(positive))
    finite = np.isfinite(values).all(axis=1)
    if not finite.any():
        raise SpectrumError(f"{path} has no finite samples in this window.")
    freq, psd = welch(values[finite], fs)
    return Spectrum(
        path=path,
        unit=info.get("unit") or "",
        fs=fs,
        nperseg=nperseg,
        segments=int(finite.sum()),
        segments_available=int(available),
        frequency=freq,
        psd=psd,
    )
