"""
How far a leg may wear before its touchdown angle's drift stops reading it: one robot, one leg.

A leg that wears is read off the forward distance's and the heading rate's slopes against run
order (docs/extensions.md). Both bend where the worn angle passes its pair partner's and the
liftoff angle changes legs (the paper's eqs. 7-8); past that the turn may stop growing with
the angle. Here the wear of one leg, made run by run outside the term's code
(`studies/outside.leg_wear`), is diagnosed at each drift given, on Table II's robot: printed
per drift the terms named, the leg's estimate with its 95 % interval (or, where its term was
not named, its last estimate and why) and whether the extended model is adequate. A
benchmark, not a test: it never fails on a number. With `--settings fast` it diagnoses with
the suite's reduced settings (test/hidden_effects.FAST: fewer simulated runs for scores and
moments), with `--settings wear` with those and the library's moment runs, as the leg-wear
tests do (hidden_effects.WEAR_SETTINGS).

With `--turns` it diagnoses nothing and prints instead, per offset of the leg's angle, the
runs' mean heading rate and forward distance, as the diagnosis's features read them
(`features.run_features`: what the term reads; 200 runs each, a second or so): where the
turn stops growing with the angle.

Run: .venv/bin/python benchmarks/bench_wear_range.py [--leg 4] [--drifts -22 -18 15 18 22]
     [--runs 300] [--seed 53] [--settings default|fast|wear] [--turns]
(five drifts of 300 runs, 5-10 minutes on one core; e.g. --turns --drifts -20 -10 0 10 20 30)
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
import sys
import time

DRIFTS_DEG = (-22.0, -18.0, 15.0, 18.0, 22.0)
REPO = Path(__file__).resolve().parents[1]
# --settings other than the library's defaults: the suite's, by their name in
# test/hidden_effects.py
SUITE_SETTINGS = {'fast': 'FAST', 'wear': 'WEAR_SETTINGS'}


def diagnose_wear(leg: int, drift_deg: float, runs: int, seed: int,
                  settings_name: str = 'default') -> str:
    """Diagnose Table II's robot with leg `leg` (1-4) drifting by `drift_deg`; one line."""
    import octoroach_model as om
    from octoroach_model.diagnosis import diagnose, DiagnosisSettings
    from octoroach_model.studies.outside import leg_wear
    from octoroach_model.model.extensions import drift_term

    measured = leg_wear(runs, drift_deg, parameters=om.ModelParameters.nominal(), seed=seed,
                        leg=leg)
    settings = DiagnosisSettings(seed=seed, detection_limits=False, workers=1)
    if settings_name in SUITE_SETTINGS:         # the suite's settings, as its tests use them
        sys.path.insert(0, str(REPO / 'test'))
        import hidden_effects
        settings = replace(getattr(hidden_effects, SUITE_SETTINGS[settings_name]), seed=seed)
    report = diagnose(measured, settings)
    term = drift_term(f'touchdown_angle_{leg}')
    worn = [e for e in report.extensions if e.term == term]
    if worn:
        low, high = worn[0].interval['change']
        held = 'holds' if low <= drift_deg <= high else 'misses'
        reading = (f'read {worn[0].parameters["change"]:+.1f} deg ({low:+.1f} to {high:+.1f}, '
                   f'{held} the truth)')
    else:
        tried = [c for c in report.extension_candidates if c.cause == term]
        reading = 'its term not named'
        if tried:                                  # the race's last word on it
            last = tried[-1]
            why = ('its held-out test failed' if last.clears_floor
                   else 'its size bound short of the floor')
            t = 'not scored' if last.held_out_t is None else f'held-out t {last.held_out_t:.2f}'
            reading += f' (read {last.parameters["change"]:+.1f} deg, {why}, {t})'
    named = ', '.join(report.named_terms) or 'nothing'
    return (f'phi{leg} {drift_deg:+.1f} deg: {reading}; named {named}; '
            f'{"adequate" if report.adequate else "not adequate"}')


def turn_and_distance(leg: int, offset_deg: float, runs: int, seed: int) -> str:
    """Return the mean heading rate (deg/s) and forward distance (cm), phi_leg offset; a line."""
    import math

    import numpy as np

    import octoroach_model as om
    from octoroach_model.diagnosis.features import INDEX, run_features

    nominal = om.ModelParameters.nominal()
    angles = list(nominal.touchdown_angles)
    angles[leg - 1] += math.radians(offset_deg)
    worn = replace(nominal, touchdown_angles=(angles[0], angles[1], angles[2], angles[3]))
    paths = om.simulate(runs, seed=seed, parameters=worn.with_paper_liftoff())
    # the features the term reads, the distance along the runs' mean start heading
    features = run_features(paths, worn.stride_frequency,
                            reference_heading=float(np.mean(paths.poses[:, 0, 2])))
    turn = np.degrees(features[:, INDEX['heading_rate']].mean())
    forward_cm = 100.0 * features[:, INDEX['end_progress']].mean()
    return (f'phi{leg} {offset_deg:+.1f} deg: heading rate {turn:+.2f} deg/s, forward '
            f'distance {forward_cm:.1f} cm (means of {runs} runs)')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--leg', type=int, choices=(1, 2, 3, 4), default=4)
    parser.add_argument('--drifts', type=float, nargs='+', default=list(DRIFTS_DEG),
                        help='deg, from the first run to the last')
    parser.add_argument('--runs', type=int, default=300)
    parser.add_argument('--seed', type=int, default=53)
    parser.add_argument('--settings', choices=('default', *SUITE_SETTINGS), default='default',
                        help="fast: the suite's reduced settings (test/hidden_effects.FAST); "
                        "wear: those with the library's moment runs, as the leg-wear tests "
                        'diagnose (hidden_effects.WEAR_SETTINGS)')
    parser.add_argument('--turns', action='store_true',
                        help='print the mean turn and distance per offset, diagnose nothing')
    args = parser.parse_args()
    if not 2 <= args.runs <= 5000 or any(abs(d) > 60 for d in args.drifts):
        parser.error('runs must be 2-5000 and every drift within +-60 deg')
    started = time.perf_counter()
    for number, drift in enumerate(args.drifts, 1):
        line = (turn_and_distance(args.leg, drift, 200, args.seed) if args.turns
                else diagnose_wear(args.leg, drift, args.runs, args.seed, args.settings))
        print(f'[{number}/{len(args.drifts)} {time.perf_counter() - started:5.0f} s] {line}',
              flush=True)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
