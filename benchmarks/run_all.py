"""
`make bench`: every benchmark in turn, each printing its own table.

Benchmarks measure; they are not timed tests and never fail on a number.
"""
from __future__ import annotations

from pathlib import Path
import subprocess
import sys

HERE = Path(__file__).resolve().parent
BENCHMARKS = ['bench_model.py', 'bench_nominal_fit.py', 'bench_diagnose.py', 'bench_fit_cost.py',
              'bench_diagnosis_tasks.py', 'bench_extension_cost.py', 'bench_nodes.py',
              'bench_validator_busy.py', 'bench_reading.py', 'bench_bag_memory.py',
              'bench_mocap_memory.py', 'bench_studies.py', 'bench_scale_out.py',
              'bench_guidance.py', 'bench_plan_calibration.py']


def main() -> int:
    failed = []
    for name in BENCHMARKS:
        print(f'\n## {name}\n', flush=True)
        if subprocess.call([sys.executable, str(HERE / name)]) != 0:
            failed.append(name)
    if failed:
        print(f'\nfailed: {", ".join(failed)}')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
