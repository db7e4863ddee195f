"""The gait seen in measured poses.

Per-run stride frequency from the heading's sway, and the average path on a common gait clock
(docs/validation.md, "The nominal fit").
"""
from __future__ import annotations

import numpy as np

from octoroach_model.paths import Paths


def heading_sway(heading: np.ndarray, dt: float, nominal: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Estimate each run's stride frequency and sway amplitude from its heading.

    The body sways once per cycle (right stance turns one way, left stance the other); how
    far depends on the leg geometry. Heading, unlike a speed from differenced positions, is
    not drowned by position noise.
    """
    centred_t = np.arange(heading.shape[1]) - 0.5 * (heading.shape[1] - 1)
    slope = (heading @ centred_t) / (centred_t @ centred_t)
    sway = heading - heading.mean(axis=1, keepdims=True) - slope[:, None] * centred_t
    window = np.hanning(sway.shape[1])
    sway *= window
    n_fft = 8192
    spectrum = np.abs(np.fft.rfft(sway, n=n_fft, axis=1))
    freqs = np.fft.rfftfreq(n_fft, dt)
    band_index = np.flatnonzero((freqs > nominal * 0.6) & (freqs < nominal * 1.4))
    rows = np.arange(heading.shape[0])
    peak = band_index[np.argmax(spectrum[:, band_index], axis=1)]
    left, centre = spectrum[rows, peak - 1], spectrum[rows, peak]
    right = spectrum[rows, np.minimum(peak + 1, len(freqs) - 1)]
    curvature = left - 2 * centre + right
    shift = np.where(curvature < 0, 0.5 * (left - right) / np.where(curvature < 0, curvature, -1),
                     0.0)
    amplitude = 2.0 * (centre - 0.25 * (left - right) * shift) / window.sum()
    return freqs[peak] + shift * (freqs[1] - freqs[0]), amplitude


def gait_aligned_average(measured: Paths, guess_hz: float
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Average path with every run put on a common gait clock.

    Runs whose strides are faster or slower than the mean would smear the plain average over
    the stance pattern; resampling run i at t * f_mean / f_i puts every run at the same gait
    phase at each time. Returns the times, the average (x, y), the average heading change
    since the start and the mean stride frequency. The grid ends where the slowest run
    (2nd percentile of the frequencies, so one bad estimate does not shorten it) ends.
    """
    t = measured.t
    heading = measured.poses[..., 2]
    frequencies, _ = heading_sway(heading, float(t[1] - t[0]), guess_hz)
    low, high = np.percentile(frequencies, [2, 98])
    frequencies = np.clip(frequencies, low, high)
    mean_frequency = float(frequencies.mean())
    grid = t[t <= t[-1] * low / mean_frequency + 1e-12]
    aligned = np.empty((measured.n_paths, len(grid), 3))
    for run, frequency in enumerate(frequencies):
        warped = grid * mean_frequency / frequency
        for column in range(3):
            aligned[run, :, column] = np.interp(warped, t, measured.poses[run, :, column])
    start_heading = measured.poses[:, :1, 2]
    turn = np.angle(np.exp(1j * (aligned[..., 2] - start_heading))).mean(axis=0)
    return grid, aligned[..., :2].mean(axis=0), turn, mean_frequency
