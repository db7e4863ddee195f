"""
Time of the main job: `diagnose` on the reference data in bags/ (500 runs), end to end.

From the bag: reading, diagnosis with both validations, report and plots; with the default
two worker processes, and with one (all in this process) for comparison; then the diagnosis
with the detection limits of one term alone and of none (`diagnose --limits`), which must
name the same terms: the limits decide nothing.

Run: .venv/bin/python benchmarks/bench_diagnose.py
"""
from __future__ import annotations

from pathlib import Path
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]
# `diagnose --limits` beside the default (all): one term's, as a lab with one question asks
LIMITS = ('lateral_slip', 'none')


def main(argv: list[str] | None = None) -> int:
    from octoroach_model.diagnosis import DiagnosisSettings, diagnose, write_report
    from octoroach_model.limit_setting import read_limits
    from octoroach_model.recordings import load_measured

    started = time.perf_counter()
    measured = load_measured([REPO / 'bags'])
    loaded = time.perf_counter()
    report = diagnose(measured, DiagnosisSettings(seed=1))
    diagnosed = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        write_report(report, out, measured=measured)
    written = time.perf_counter()
    single = time.perf_counter()
    diagnose(measured, DiagnosisSettings(seed=1, workers=1))
    single = time.perf_counter() - single
    fewer = {}
    for limits in LIMITS:
        detection_limits, limit_terms = read_limits(limits)
        started_fewer = time.perf_counter()
        other = diagnose(measured, DiagnosisSettings(seed=1, detection_limits=detection_limits,
                                                     limit_terms=limit_terms))
        fewer[limits] = time.perf_counter() - started_fewer
        if tuple(other.named_terms) != tuple(report.named_terms):
            print(f'error: --limits {limits} named {tuple(other.named_terms)}, with every '
                  f'limit {tuple(report.named_terms)}', file=sys.stderr)
            return 1
    print('| step | seconds |')
    print('| --- | --- |')
    print(f'| read and split {measured.n_paths} runs from bags/ | {loaded - started:.1f} |')
    print(f'| diagnose (incl. two validations), 2 worker processes | {diagnosed - loaded:.1f} |')
    print(f'| report and plots | {written - diagnosed:.1f} |')
    print(f'| total | {written - started:.1f} |')
    print(f'| diagnose with 1 process (for comparison) | {single:.1f} |')
    for limits, seconds in fewer.items():
        print(f'| diagnose, 2 worker processes, `--limits {limits}` | {seconds:.1f} |')
    print('causes: ' + (', '.join(f'{c.cause} {c.parameters}' for c in report.causes) or 'none')
          + f'; adequate: {report.adequate}')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
