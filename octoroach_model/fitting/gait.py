"""
The gait seen in measured poses.

Per-run stride frequency from the heading's sway, and the average path on a common gait clock
(docs/validation.md, "The nominal fit").

Runs may end early (NaN tails, see `Paths`): every per-run quantity here uses each run's own
samples, and averages over time use the runs still present at that time.
"""
from __future__ import annotations

import numpy as np

from octoroach_model.arrays import BoolArray, FloatArray, IntArray
from octoroach_model.model.trig import cos_sin
from octoroach_model.paths import Paths

BAND = (0.6, 1.4)         # the stride frequency is sought within this factor of the guess
BAND_POINTS = 33          # DFT frequencies across the band (then a parabolic refinement)
SPECTRUM_RUNS = 400       # runs averaged for the set's stride frequency (plenty for a peak)


def valid_mask(values: FloatArray) -> BoolArray:
    """(n, T) True where a run has a sample (runs are NaN after their end)."""
    return np.isfinite(values)


def hann_windows(lengths: IntArray, n_samples: int) -> FloatArray:
    """(n, T) a Hann window over each run's own samples, zero after its end."""
    distinct, which = np.unique(lengths, return_inverse=True)   # most runs share a length
    index = np.arange(n_samples)[None, :]
    span = np.maximum(distinct[:, None] - 1, 1)
    window = 0.5 - 0.5 * np.cos(2 * np.pi * index / span)
    return np.where(index < distinct[:, None], window, 0.0)[which.reshape(-1)]


def detrended(values: FloatArray, t: FloatArray) -> FloatArray:
    """
    Each run minus its own least-squares line over its samples; 0 after its end.

    Parameters
    ----------
    values : array, shape (n, T)
        NaN after a run's end.
    t : array, shape (T,)
        s.

    Returns
    -------
    array, shape (n, T)
        In the units of `values`.

    """
    mask = valid_mask(values)
    if mask.all():
        return _detrended_whole(values, t)
    weight = mask.astype(float)
    count = np.maximum(weight.sum(axis=1, keepdims=True), 1)
    filled = np.where(mask, values, 0.0)
    t_mean = (weight * t).sum(axis=1, keepdims=True) / count
    v_mean = filled.sum(axis=1, keepdims=True) / count
    centred_t = (t - t_mean) * weight
    slope = (centred_t * (filled - v_mean)).sum(axis=1, keepdims=True) \
        / np.maximum((centred_t ** 2).sum(axis=1, keepdims=True), 1e-300)
    return np.where(mask, filled - v_mean - slope * (t - t_mean), 0.0)


def _detrended_whole(values: FloatArray, t: FloatArray) -> FloatArray:
    """
    `detrended` where every run has every sample (simulated runs, most recordings).

    The same arithmetic with the weights of 1 and the masks left out, and the line's times
    shared by all runs: bit-identical to the masked form (a row's sum is its own 1-D sum),
    at half its cost.
    """
    count = max(len(t), 1)
    t_mean = t.sum() / count
    centred: FloatArray = values - values.sum(axis=1, keepdims=True) / count
    centred_t = t - t_mean
    slope = (centred_t * centred).sum(axis=1, keepdims=True) / max((centred_t ** 2).sum(), 1e-300)
    centred -= slope * centred_t        # values - v_mean - slope (t - t_mean), as masked
    return centred


def band_spectrum(signal: FloatArray, t: FloatArray, frequencies: FloatArray) -> FloatArray:
    """
    |DFT| of each (windowed, zero-filled) run at `frequencies` (Hz): (n, K).

    A DFT on a few frequencies in a band costs n T K, far less than a finely zero-padded FFT
    of every run, and its frequency grid is the same whatever the sample rate.

    Parameters
    ----------
    signal : array, shape (n, T)
        Windowed runs, zero after their end.
    t : array, shape (T,)
        s.
    frequencies : array, shape (K,)
        Hz.

    Returns
    -------
    array, shape (n, K)
        In the units of `signal`.

    """
    cosine, sine = cos_sin(2 * np.pi * np.outer(t, frequencies))
    # two real products: a real signal times a complex matrix is four
    return np.hypot(signal @ cosine, signal @ sine)


def windowed_sway(heading: FloatArray, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """
    Return each run's heading, its own line removed, times its Hann window; and the window.

    Parameters
    ----------
    heading : array, shape (n, T)
        rad, NaN after a run's end.
    t : array, shape (T,)
        s.

    Returns
    -------
    sway, window : arrays, shape (n, T)
        rad, and the window (0..1).

    """
    lengths = valid_mask(heading).sum(axis=1)
    window = hann_windows(lengths, heading.shape[1])
    return detrended(heading, t) * window, window


def heading_sway(heading: FloatArray, t: FloatArray, nominal_hz: float,
                 windowed: tuple[FloatArray, FloatArray] | None = None
                 ) -> tuple[FloatArray, FloatArray]:
    """
    Per-run stride frequency (Hz) and sway amplitude (rad) of the heading.

    The body sways once per cycle (the right stance turns it one way, the left the other);
    how far depends on the leg geometry. Heading, unlike a speed from differenced positions,
    is not drowned by position noise. The peak of the windowed spectrum within BAND of
    `nominal_hz` is refined by a parabola through its neighbours. `windowed`: the result of
    `windowed_sway`, where the caller has it already.

    Parameters
    ----------
    heading : array, shape (n, T)
        rad, NaN after a run's end.
    t : array, shape (T,)
        s.
    nominal_hz : float
        Hz.
    windowed : (sway, window) or None
        `windowed_sway` of `heading`, where the caller has it.

    Returns
    -------
    frequency, amplitude : arrays, shape (n,)
        Hz, rad.

    """
    sway, window = windowed if windowed is not None else windowed_sway(heading, t)
    frequencies = np.linspace(BAND[0] * nominal_hz, BAND[1] * nominal_hz, BAND_POINTS)
    spectrum = band_spectrum(sway, t, frequencies)
    rows = np.arange(heading.shape[0])
    peak = np.clip(np.argmax(spectrum, axis=1), 1, BAND_POINTS - 2)
    left, centre, right = (spectrum[rows, peak - 1], spectrum[rows, peak],
                           spectrum[rows, peak + 1])
    curvature = left - 2 * centre + right
    shift = np.where(curvature < 0, 0.5 * (left - right) / np.where(curvature < 0, curvature, -1),
                     0.0)
    shift = np.clip(shift, -1.0, 1.0)
    step = frequencies[1] - frequencies[0]
    amplitude = 2.0 * (centre - 0.25 * (left - right) * shift) / np.maximum(
        window.sum(axis=1), 1e-12)
    return frequencies[peak] + shift * step, amplitude


def lateral_sway(xy: FloatArray, heading: FloatArray, t: FloatArray,
                 frequency: FloatArray, window: FloatArray | None = None
                 ) -> tuple[FloatArray, FloatArray]:
    """
    Measure the sideways sway of G (m) at each run's stride frequency and twice it.

    Sideways is across the run's mean heading, linear trend removed; the two amplitudes are
    the shape of a stance.

    Parameters
    ----------
    xy : array, shape (n, T, 2)
        m.
    heading : array, shape (n, T)
        rad.
    t : array, shape (T,)
        s.
    frequency : array, shape (n,)
        Each run's stride frequency, Hz.
    window : array, shape (n, T), or None
        Each run's Hann window (`windowed_sway`'s), where the caller has it.

    Returns
    -------
    at_f, at_2f : arrays, shape (n,)
        m.

    """
    mask = valid_mask(heading)
    lengths = mask.sum(axis=1, keepdims=True)
    count = np.maximum(lengths, 1)
    whole = bool(mask.all())       # no run ends early: nothing to mask (the same sums)
    mean_heading = (heading if whole else np.where(mask, heading, 0.0)).sum(
        axis=1, keepdims=True) / count
    across = xy[..., 0] * np.sin(mean_heading) - xy[..., 1] * np.cos(mean_heading)
    if window is None:
        window = hann_windows(lengths[:, 0], len(t))
    residual = detrended(across, t) * window
    norm = np.maximum(window.sum(axis=1), 1e-12)
    angle = 2 * np.pi * frequency[:, None] * t[None, :]
    cos, sin = cos_sin(angle)      # real arithmetic: a complex exp costs 3x

    def amplitude(cosine: FloatArray, sine: FloatArray) -> FloatArray:
        projections = (np.einsum('ij,ij->i', residual, cosine),
                       np.einsum('ij,ij->i', residual, sine))
        amplitudes: FloatArray = 2 * np.hypot(*projections) / norm
        return amplitudes

    first = amplitude(cos, sin)
    return first, amplitude(cos * cos - sin * sin, 2 * sin * cos)     # twice the angle


def stride_samples(stride_frequency: float, dt: float) -> int:
    """Return the samples of one stride cycle (at least 2): the window of `slip_angle`."""
    return max(2, int(round(1.0 / (stride_frequency * dt))))


def cycle_distances(xy: FloatArray, cycle: int) -> FloatArray:
    """
    Return the (n, T - cycle) distance each run covers over each window of `cycle` samples.

    A stride's worth of samples (`stride_samples`) takes the sway out of a speed: what a
    change of speed within a run is read from (the change point's fit and its plot). NaN
    where a window reaches past a run's end.
    """
    dx, dy = cycle_steps(xy, cycle)
    distances: FloatArray = np.sqrt(dx * dx + dy * dy)  # the sums np.linalg.norm makes
    return distances


def cycle_steps(xy: FloatArray, cycle: int) -> tuple[FloatArray, FloatArray]:
    """
    Return the (n, T - cycle) x and y each run moves over each window of `cycle` samples.

    Each coordinate apart: numpy walks a (..., 2) array two numbers at a time (its inner loop
    is the last axis). NaN where a window reaches past a run's end.
    """
    x, y = xy[..., 0], xy[..., 1]
    return x[:, cycle:] - x[:, :-cycle], y[:, cycle:] - y[:, :-cycle]


def slip_angle(xy: FloatArray, heading: FloatArray, cycle: int) -> FloatArray:
    """
    Per run, the mean over cycle-long windows of (direction of travel - mean heading), rad.

    The heading to travel angle: the model's comes from the difference of its second and
    fourth touchdown angles (a body that crabs), which neither the average path nor the sway
    pins down on few long runs.
    """
    step_x, step_y = cycle_steps(xy, cycle)
    filled = heading if np.isfinite(heading).all() else np.nan_to_num(heading)
    total = np.zeros((heading.shape[0], heading.shape[1] + 1))
    np.cumsum(filled, axis=1, out=total[:, 1:])
    mean_heading = (total[:, cycle + 1:] - total[:, :-cycle - 1]) * (1.0 / (cycle + 1))
    # the step turned into the mean heading's frame: its angle is already within [-pi, pi]
    # (np.remainder on the difference of two angles cost as much as the rest together)
    cos, sin = cos_sin(mean_heading)
    along = step_x * cos + step_y * sin
    across = step_y * cos - step_x * sin
    offset = np.arctan2(across, along)
    usable = np.isfinite(step_x)
    count = np.maximum(usable.sum(axis=1), 1)
    mean_offset: FloatArray = (offset if usable.all() else np.where(usable, offset, 0.0)).sum(
        axis=1) / count
    return mean_offset


# the columns of `gait_features`, named as the diagnosis's run features name them
GAIT_FEATURES = ('sway_amplitude', 'lateral_sway_1', 'lateral_sway_2', 'stride_frequency',
                 'slip_angle')


def gait_features(t: FloatArray, xy: FloatArray, heading: FloatArray,
                  guess_hz: float, cycle: int,
                  windowed: tuple[FloatArray, FloatArray] | None = None) -> FloatArray:
    """
    (n, 5) per run, columns `GAIT_FEATURES`: the sway, the strides and the travel angle.

    In rad, m, m, Hz, rad; the last is the heading to travel angle (`slip_angle`).

    Parameters
    ----------
    t : array, shape (T,)
        s.
    xy : array, shape (n, T, 2)
        m.
    heading : array, shape (n, T)
        rad.
    guess_hz : float
        Stride frequency guess, Hz.
    cycle : int
        Samples of the window of the heading to travel angle (`stride_samples`).
    windowed : (sway, window) or None
        `windowed_sway` of `heading`, where the caller has it.

    """
    windowed = windowed if windowed is not None else windowed_sway(heading, t)
    frequency, amplitude = heading_sway(heading, t, guess_hz, windowed)
    first, second = lateral_sway(xy, heading, t, frequency, windowed[1])
    return np.column_stack([amplitude, first, second, frequency,
                            slip_angle(xy, heading, cycle)])


def stride_frequency_estimate(heading: FloatArray, t: FloatArray) -> float:
    """
    Estimate the stride frequency (Hz) of a set of runs, with no prior guess.

    It is the peak of the mean power spectrum of the heading's sway, whitened by f^2 so that
    the slow wander of a random-walk heading (power falling as 1/f^2) cannot outweigh the
    once-per-cycle sway.

    Searched from 1.5 cycles per run up to a third of the sample rate, on the first
    SPECTRUM_RUNS runs.

    Parameters
    ----------
    heading : array, shape (n, T)
        rad, NaN after a run's end.
    t : array, shape (T,)
        s.

    """
    lengths = valid_mask(heading).sum(axis=1)
    usable = np.flatnonzero(lengths >= 8)[:SPECTRUM_RUNS]
    if not usable.size:
        return float('nan')
    heading, lengths = heading[usable], lengths[usable]
    sway = detrended(heading, t) * hann_windows(lengths, heading.shape[1])
    n_fft = 1 << int(np.ceil(np.log2(heading.shape[1] * 8)))
    n_fft = max(min(n_fft, 1 << 17), 1 << int(np.ceil(np.log2(heading.shape[1]))))
    dt = float(t[1] - t[0])
    power = (np.abs(np.fft.rfft(sway, n=n_fft, axis=1)) ** 2).mean(axis=0)
    frequencies = np.fft.rfftfreq(n_fft, dt)
    duration = float(np.median(lengths - 1)) * dt
    band = (frequencies >= 1.5 / duration) & (frequencies <= 1.0 / (3 * dt))
    if not band.any():
        return float('nan')
    return float(frequencies[band][np.argmax((power * frequencies ** 2)[band])])


def aligned_runs(measured: Paths, guess_hz: float
                 ) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """
    Put every run on a common gait clock.

    Return the grid (G,), the runs' (x, y) on it (n, G, 2), their heading change since their
    start (n, G) and the mean stride frequency.

    Runs whose strides are faster or slower than the mean would smear the plain average over
    the stance pattern; resampling run i at t * f_mean / f_i puts every run at the same gait
    phase at each time. The grid ends where the slowest run (2nd percentile of the
    frequencies, so one bad estimate does not shorten it) ends; a run that ends early is NaN
    after its end.
    """
    t = measured.t
    heading = measured.poses[..., 2]
    frequencies, _ = heading_sway(heading, t, guess_hz)
    low, high = np.percentile(frequencies, [2, 98])
    frequencies = np.clip(frequencies, low, high)
    mean_frequency = float(frequencies.mean())
    grid = t[t <= t[-1] * low / mean_frequency + 1e-12]
    warped = grid[None, :] * (mean_frequency / frequencies)[:, None]      # (n, G)
    aligned = np.stack([_interp_rows(warped, t, measured.poses[..., column])
                        for column in range(3)], axis=-1)
    turn = np.angle(np.exp(1j * (aligned[..., 2] - measured.poses[:, :1, 2])))
    return grid, aligned[..., :2], turn, mean_frequency


def _interp_rows(at: FloatArray, t: FloatArray, values: FloatArray) -> FloatArray:
    """
    Interpolate values (n, T) sampled at t linearly, row by row, at times at (n, G).

    NaN beyond a run's end (no extrapolation).
    """
    dt = float(t[1] - t[0])
    position = at / dt
    left = np.clip(np.floor(position).astype(int), 0, len(t) - 2)
    fraction = position - left
    rows = np.arange(values.shape[0])[:, None]
    low, high = values[rows, left], values[rows, left + 1]
    result = low + fraction * (high - low)
    return np.where(position <= len(t) - 1 + 1e-9, result, np.nan)
