"""
The thorough profile of the robot-space property test: many robots at full size.

`make test` runs test/test_robot_space.py with a few small examples; this runs the same
property (every robot gets a result or a one-line DataError, and a report is always written)
with OCTOROACH_ROBOT_SPACE=thorough: 60 examples, up to 3000 runs and 20 000 samples per run.
It takes about an hour on two cores. The false-positive rate over the same space is a study:
`python -m octoroach_model study studies/wide_robots.yaml --out out/studies/wide_robots`.

Run: .venv/bin/python benchmarks/bench_robot_space.py [--seed N]
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import subprocess
import sys
import time

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    """Run the property test's thorough profile and print how long it took."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seed', type=int, default=2013, help='OCTOROACH_TEST_SEED')
    args = parser.parse_args(argv)
    env = {**os.environ, 'OCTOROACH_ROBOT_SPACE': 'thorough',
           'OCTOROACH_TEST_SEED': str(args.seed)}
    started = time.perf_counter()
    code = subprocess.call([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                            str(REPO / 'test' / 'test_robot_space.py')], cwd=REPO, env=env)
    print(f'robot space, thorough profile (seed {args.seed}): '
          f'{"passed" if code == 0 else "FAILED"} in {time.perf_counter() - started:.0f} s')
    return code


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
