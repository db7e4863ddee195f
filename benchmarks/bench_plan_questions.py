"""
Does `plan`'s answer hold on real questions? Its interval against the term's own power curve.

For each question TERM=SIZE (Table II's robot, as `plan` takes it by default): `plan`
(`--method model`, two workers) answers with a run count and a 95 % interval; then the
term's first step is taken as plan's checks take it (`plan_model.check_task`: the term at
the size, the diagnosis's levels) on PER new data sets (replicates from 7000, seeds plan
never uses) at the interval's ends and at the answer, or at `--counts`. Printed: the answer,
and the share named at each count with its Wilson interval. Where the interval holds the
true 80 % point, the share at its low end is below 80 % and at its high end above.

Run: .venv/bin/python benchmarks/bench_plan_questions.py TERM=SIZE [TERM=SIZE ...]
     [--counts N,N,...] [--per 24]
The README's figures ("How many runs: plan"): initial_pose_error=15 --counts 50,70,90,110
(76 s), and lateral_slip=0.3 gait_frequency_variation=0.008 heading_random_walk=1.0
run_order_drift:yaw_rate=6 periodic_heading=2.0 measurement_noise=0.015 initial_pose_error=15
persistent_turning=3 (about 13 minutes).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

FIRST_REPLICATE = 7000


def question(text: str) -> tuple[str, float]:
    """Return (term, size) of a TERM=SIZE argument; refuse anything else in argparse's way."""
    from octoroach_model.limit_setting import RACED_TERMS

    term, _, size = text.partition('=')
    if term not in RACED_TERMS:
        raise argparse.ArgumentTypeError(f'{term[:60]!r} is not a term: one of '
                                         f'{", ".join(RACED_TERMS)}')
    try:
        value = float(size)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text[:60]!r}: the size after = is not a number') \
            from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f'{text[:60]!r}: the size must be a positive number')
    return term, value


def counts_of(text: str) -> list[int]:
    """Return the sorted run counts of a comma-separated --counts (each at least 40)."""
    try:
        counts = sorted({int(value) for value in text.split(',')})
    except ValueError:
        raise argparse.ArgumentTypeError('--counts takes whole numbers, comma-separated') \
            from None
    if not counts or counts[0] < 40 or counts[-1] > 100_000:
        raise argparse.ArgumentTypeError('--counts: each count between 40 and 100000')
    return counts


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('questions', nargs='+', metavar='TERM=SIZE', type=question)
    parser.add_argument('--counts', default=None, type=counts_of,
                        help='run counts, comma-separated')
    parser.add_argument('--per', type=int, default=24, help='data sets at each count')
    arguments = parser.parse_args()
    import octoroach_model as om
    from octoroach_model.diagnosis.live import Question
    from octoroach_model.studies.plan import _base_spec
    from octoroach_model.studies.plan_model import check_task
    from octoroach_model.studies.summary import wilson
    from octoroach_model.workers import executor_for

    for term, size in arguments.questions:
        started = time.perf_counter()
        result = om.plan_runs(term, size, workers=2)
        low, high = result.runs_needed_interval_95
        print(f'{term}={size:g}: {result.statement} ({time.perf_counter() - started:.1f} s)',
              flush=True)
        if arguments.counts:
            counts = arguments.counts
        elif result.runs_needed is None or low is None or high is None \
                or not math.isfinite(high):
            continue
        else:
            counts = sorted({max(40, round(low)), int(result.runs_needed), round(high)})
        spec = _base_spec(term, size, None, None, 6, 0, None, 40, 2000, 0.8)
        asked = Question(term, size)
        with executor_for(None, 2) as pool:
            futures = {runs: [pool.submit(check_task, spec, asked, runs,
                                          FIRST_REPLICATE + replicate)
                              for replicate in range(arguments.per)] for runs in counts}
            for runs in counts:
                done = [future.result() for future in futures[runs]]
                ok = [outcome for outcome in done if outcome.status == 'ok']
                rate = wilson(sum(outcome.named for outcome in ok), len(ok))
                assert rate.rate is not None and rate.interval is not None
                print(f'    {runs} runs: named in {rate.successes}/{rate.trials} = '
                      f'{rate.rate:.0%} ({rate.interval[0]:.0%}-{rate.interval[1]:.0%})',
                      flush=True)
        print(f'    ({time.perf_counter() - started:.0f} s)', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
