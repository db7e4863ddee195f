"""
No crash anywhere in the robot space.

Every robot the model can describe gets a result, or the package's DataError with a one-line
reason naming the limit its data miss.

Hypothesis draws robots (strides 0.5-6 Hz, 30-500 Hz sampling, 3-40 cycles, touchdown angles
within 10 deg of Table II, leg 1.5-3 cm), data sets (40-3000 runs; here capped for time, see
PROFILE), runs cut short (70-95 % of their duration) and dropped frames (interpolated, as the
bag reader fills them). `fit_nominal`, `validate`, `diagnose` (with the detection limits of
no term or of one, and in the thorough profile of every term: drawn too, and computed for
those alone) and `write_report` (with plots) must each return, or raise DataError; a plot that
cannot be drawn must not cost the report.

Profiles: the suite's (OCTOROACH_ROBOT_SPACE=quick, the default: few examples, small data, few
simulated runs in the diagnosis, no example with every limit) and the thorough one
(OCTOROACH_ROBOT_SPACE=thorough, from benchmarks/bench_robot_space.py: many examples at full
size, twice the simulated runs, every limit in about a third of them).
Draws are seeded by the suite seed (pytest's header), so a failure replays with the same
OCTOROACH_TEST_SEED; Hypothesis also prints the failing example.
"""
from __future__ import annotations

from dataclasses import replace
import math
import os

from hypothesis import given, HealthCheck, seed, settings, strategies as st
import numpy as np
import pytest

import octoroach_model as om
from octoroach_model.diagnosis import diagnose, DiagnosisSettings, write_report
from octoroach_model.diagnosis.records import LimitMethod
from octoroach_model.diagnosis.summary import spread_ceiling_line
from octoroach_model.fitting import fit_nominal
from octoroach_model.limit_setting import RACED_TERMS, read_limits
from octoroach_model.validation import validate, ValidationSettings

# The quick profile's diagnosis simulates half as many runs as the thorough one's: what the
# property asks (a result or a one-line reason) does not depend on the simulations' noise.
# Its runs are capped at 600 samples (at least 3 cycles): an example's cost grows with its
# samples (the 500 Hz draws with limits took 25 s at 1200), and the thorough profile draws
# runs up to 20000 samples. The quick profile computes the detection limits of no term or of
# one term drawn from the fourteen, not of all at once: an example with all of them took two
# to four times one with none (19.4 and 11.1 s against 3.5-9.4 s at suite seed 31337), and
# each term's limit still meets random robots, one term an example; the thorough profile and
# the report test (test_diagnosis.py) compute all of them.
PROFILES = {
    'quick': {'examples': 6, 'max_runs': 90, 'max_samples': 600, 'limits': ('none', 'one'),
              'simulated_runs': {'score_runs': 100, 'moment_runs': 60, 'mean_path_runs': 40,
                                 'discrepancy_runs': 100, 'bootstrap': 10}},
    'thorough': {'examples': 60, 'max_runs': 3000, 'max_samples': 20000,
                 'limits': ('none', 'all', 'one'),
                 'simulated_runs': {'score_runs': 200, 'moment_runs': 120, 'mean_path_runs': 80,
                                    'discrepancy_runs': 200, 'bootstrap': 20}},
}
PROFILE = PROFILES[os.environ.get('OCTOROACH_ROBOT_SPACE', 'quick')]
SUITE_SEED = int(os.environ.get('OCTOROACH_TEST_SEED', '0'))
TINY = DiagnosisSettings(validate_models=False, workers=1, **PROFILE['simulated_runs'])
SMALL_VALIDATION = ValidationSettings(epsilon=0.4, delta=0.4, k=3, grid_points=3)


@st.composite
def data_sets(draw) -> tuple[om.Paths, str, bool]:
    nominal = om.ModelParameters.nominal()
    offsets = [draw(st.floats(-10, 10)) for _ in range(4)]
    frequency = draw(st.floats(0.5, 6.0))
    rate = draw(st.sampled_from([30.0, 50.0, 100.0, 200.0, 500.0]))
    cycles = draw(st.integers(3, 40))
    cycles = max(3, min(cycles, int(PROFILE['max_samples'] * frequency / rate)))
    robot = replace(nominal, leg_length=draw(st.floats(0.015, 0.03)),
                    touchdown_angles=tuple(a + math.radians(o) for a, o in
                                           zip(nominal.touchdown_angles, offsets)),
                    stride_frequency=frequency, sample_rate=rate).with_paper_liftoff()
    runs = draw(st.integers(40, min(3000, PROFILE['max_runs'])))
    spread = draw(st.floats(0.3, 1.5))
    sigma1, sigma2 = om.model.nominal_sigmas()
    paths = om.simulate(runs, seed=draw(st.integers(0, 10_000)), cycles=cycles,
                        parameters=robot, sigma1=sigma1 * spread, sigma2=sigma2 * spread)
    rng = np.random.default_rng(draw(st.integers(0, 10_000)))
    paths = drop_frames(paths, draw(st.floats(0.0, 0.05)), rng)
    lengths = np.full(runs, len(paths.t))
    cut = rng.random(runs) < draw(st.floats(0.0, 0.3))
    lengths[cut] = np.maximum(2, (rng.uniform(0.7, 0.95, cut.sum()) * len(paths.t)).astype(int))
    limits = draw(st.sampled_from(PROFILE['limits']))     # diagnose --limits
    if limits == 'one':
        limits = draw(st.sampled_from(RACED_TERMS))
    case = (f'{runs} runs, {cycles} cycles at {frequency:.2f} Hz, {rate:.0f} Hz, leg '
            f'{robot.leg_length * 100:.2f} cm, angles {np.round(offsets, 1).tolist()} deg off, '
            f'spread x{spread:.2f}, {int(cut.sum())} cut short, limits {limits}')
    return paths.cut_to(lengths), case, limits


def drop_frames(paths: om.Paths, share: float, rng: np.random.Generator) -> om.Paths:
    """Frames lost in transmission, filled by linear interpolation as the reader fills them."""
    poses = paths.poses.copy()
    lost = rng.random(poses.shape[:2]) < share
    lost[:, [0, -1]] = False
    index = np.arange(len(paths.t))
    for run in np.flatnonzero(lost.any(axis=1)):
        kept = ~lost[run]
        for column in range(3):
            poses[run, :, column] = np.interp(index, index[kept], poses[run, kept, column])
    return om.Paths(paths.t, poses)


def test_the_drop_helper_interpolates_only_the_dropped_frames() -> None:
    paths = om.simulate(3, seed=1, cycles=2)
    dropped = drop_frames(paths, 0.2, np.random.default_rng(0))
    assert np.isfinite(dropped.poses).all()
    assert 0 < np.count_nonzero(dropped.poses != paths.poses) < paths.poses.size


@pytest.mark.long
@seed(SUITE_SEED)
@settings(max_examples=PROFILE['examples'], deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])
@given(data_sets())
def test_every_robot_gets_a_result_or_a_one_line_reason(tmp_path_factory, case) -> None:
    measured, description, limits = case
    try:
        fit = fit_nominal(measured)
        assert np.isfinite(fit.rms_error_m), description
        result = validate(measured.truncated(float(measured.t[min(measured.lengths) - 1])),
                          SMALL_VALIDATION, om.FourBarModel(fit.parameters, fit.start_pose))
        assert 0.0 <= result.violation <= 1.0, description
    except om.DataError as error:
        assert '\n' not in str(error) and str(error), description
    try:
        detection_limits, limit_terms = read_limits(limits)
        report = diagnose(measured, replace(TINY, detection_limits=detection_limits,
                                            limit_terms=limit_terms))
    except om.DataError as error:
        message = str(error)
        assert '\n' not in message and ('at least' in message or 'no stride' in message), \
            f'{description}: {message}'
        return
    out = tmp_path_factory.mktemp('report')
    written = write_report(report, out, measured=measured)
    assert written['report'].stat().st_size > 0 and written['summary'].stat().st_size > 0
    ceiling = spread_ceiling_line(report)        # few held-out runs: said in the summary
    assert ceiling is None or ceiling in written['summary'].read_text(), description
    assert report.runs.ended_early == int(np.count_nonzero(measured.lengths < len(measured.t)))
    candidates = report.candidates + report.extension_candidates
    whole = {c.cause for c in candidates if c.detectable_method == LimitMethod.WHOLE_DECISION}
    asked = {c.cause for c in candidates} if limits == 'all' else set(limit_terms)
    assert whole == asked, description
