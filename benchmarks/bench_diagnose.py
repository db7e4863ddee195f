"""
Time of the main job: `diagnose` on the reference data in bags/ (500 runs), end to end.

From the bag: reading, diagnosis with both validations, report and plots; with the default
two worker processes, and with one (all in this process) for comparison.

Run: .venv/bin/python benchmarks/bench_diagnose.py
"""
from __future__ import annotations

from pathlib import Path
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    from octoroach_model.diagnosis import DiagnosisSettings, diagnose, write_report
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
    print('| step | seconds |')
    print('| --- | --- |')
    print(f'| read and split {measured.n_paths} runs from bags/ | {loaded - started:.1f} |')
    print(f'| diagnose (incl. two validations), 2 worker processes | {diagnosed - loaded:.1f} |')
    print(f'| report and plots | {written - diagnosed:.1f} |')
    print(f'| total | {written - started:.1f} |')
    print(f'| diagnose with 1 process (for comparison) | {single:.1f} |')
    print('causes: ' + (', '.join(f'{c.cause} {c.parameters}' for c in report.causes) or 'none')
          + f'; adequate: {report.adequate}')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
