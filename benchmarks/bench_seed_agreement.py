"""
Whether the diagnosis names the same terms on the same runs when only its seed changes.

The diagnosis draws its split of the runs into halves and every simulation from its seed
(`diagnose --seed`). On the same runs, a decision that changes with the seed rests on those
draws, not on the data. This counts how often that happens, on data sets of finished studies
rebuilt as each study built them (`study_replay.rebuilt`: the replicate's robot and seed from
the spec, the size put in read off the null data set's limit in the study's table.csv). Each
data set is diagnosed at the study's seed and again with the seed moved by 1, ..., K, the
study's settings otherwise; with `--keep-split`, also with the seed moved but the halves kept
(`DiagnosisSettings.split_seed`): the simulations' share alone. Printed per study arm: the data
sets whose named terms were the same at every seed, with a 95 % Wilson interval, how many
named the arm's term at each seed, and each data set whose named terms changed. The first
diagnosis is checked against the study's row.

Arms at 1x a detection limit are where it matters: the limit is the size named in 80 % of data
sets, so some of them sit near the decision's threshold. Null data sets are left out (their
limits double the cost; a named term on them is rare, docs/measured.md, "False positives").

Every diagnosis is appended to `--results` (JSON lines, with the commit it ran at) as it ends;
one already there is not run again (unless `--again`), so an interrupted run resumes and
`--keep-split` adds to an earlier run. `--report-only` prints the tables from the file.
About a minute of one core per data set and seed (500 runs).
Run: .venv/bin/python benchmarks/bench_seed_agreement.py [--studies periodic_limits
     mixture_limits] [--arms @1x @+-1x] [--seeds 1] [--keep-split] [--workers 2]
"""
from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import replace
import json
from pathlib import Path
import subprocess
import sys
import time
from typing import Any, NamedTuple

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))
RESULTS = REPO / 'out' / 'bench_seed_agreement' / 'results.jsonl'


class Job(NamedTuple):
    """One data set of a study, diagnosed with the seed moved by `shift`."""

    study: str
    key: str
    shift: int
    keep_split: bool     # the halves of the study's seed (the simulations' draws moved alone)


class Diagnosed(NamedTuple):
    """A job's outcome: what it named, the CPU it took, and the commit it ran at."""

    job: Job
    named: tuple[str, ...]
    cpu_s: float
    commit: str


def diagnosed(job: Job, null_row: Any, commit: str) -> Diagnosed:
    """Rebuild the study's data set and diagnose it as the job says."""
    from study_replay import rebuilt

    from octoroach_model.diagnosis import diagnose
    from octoroach_model.diagnosis.diagnose import redraw_settings
    from octoroach_model.studies.design import build_tasks
    from octoroach_model.studies.spec import load_spec

    started = time.process_time()
    spec = load_spec(REPO / 'studies' / f'{job.study}.yaml')
    task = next(task for task in build_tasks(spec) if task.key == job.key)
    data = rebuilt(spec, task, null_row)
    # halves kept: a draw as `diagnose --simulation-draws` makes it (the study's arms have
    # neither limits nor validations either); else the split moves with the seed
    settings = (redraw_settings(data.settings, job.shift) if job.keep_split
                else replace(data.settings, seed=data.settings.seed + job.shift, workers=1))
    report = diagnose(data.measured, settings)
    return Diagnosed(job, tuple(report.named_terms), round(time.process_time() - started, 1),
                     commit)


def study_rows(study: str, arms: Sequence[str]) -> list[tuple[Any, Any]]:
    """Return (row, its replicate's null row) for the study's data sets of the chosen arms."""
    from octoroach_model.studies.table import read_table

    table = REPO / 'out' / 'studies' / study / 'table.csv'
    if not table.is_file():
        raise SystemExit(f'needs the study table: run studies/{study}.yaml into {table.parent}')
    rows = read_table(table)[0]
    nulls = {row.replicate: row for row in rows if row.arm == 'none'}
    return [(row, nulls.get(row.replicate)) for row in rows
            if row.status == 'ok' and any(arm in row.key for arm in arms)]


def read_results(path: Path) -> dict[Job, Diagnosed]:
    """Return the diagnoses in the results file (a cut-off last line is left out)."""
    found: dict[Job, Diagnosed] = {}
    if not path.is_file():
        return found
    for line in path.read_text(encoding='utf-8').splitlines():
        try:
            entry = json.loads(line)
            job = Job(entry['study'], entry['key'], int(entry['shift']),
                      bool(entry['keep_split']))
            found[job] = Diagnosed(job, tuple(entry['named']), float(entry['cpu_s']),
                                   str(entry['commit']))
        except (ValueError, KeyError, TypeError):
            continue
    return found


def append_result(path: Path, result: Diagnosed) -> None:
    """Append one diagnosis to the results file as a line of JSON, flushed at once."""
    from octoroach_model.fileio import appended_lines

    with appended_lines(path) as stream:
        stream.write(json.dumps({**result.job._asdict(), 'named': list(result.named),
                                 'cpu_s': result.cpu_s, 'commit': result.commit}) + '\n')
        stream.flush()


def named_by_seed(study: str, key: str, results: dict[Job, Diagnosed], seeds: int,
                  keep_split: bool) -> list[tuple[str, ...]] | None:
    """
    Return what one data set's diagnoses named at the study's seed and at each moved one.

    The study's seed first (its own split), then seed + 1..`seeds` with the split moved too or,
    with `keep_split`, kept; None while one of them is missing from `results`.
    """
    jobs = [Job(study, key, shift, keep_split and shift > 0) for shift in range(seeds + 1)]
    if not all(job in results for job in jobs):
        return None
    return [results[job].named for job in jobs]


def agreement_rows(tables: dict[str, list[tuple[Any, Any]]], results: dict[Job, Diagnosed],
                   seeds: int) -> list[str]:
    """Return the table's lines: per study arm, the data sets named alike at every seed."""
    from octoroach_model.studies.summary import wilson

    def same(sets: list[list[tuple[str, ...]]]) -> str:
        agreed = sum(len(set(named)) == 1 for named in sets)
        rate = wilson(agreed, len(sets))
        low, high = rate.interval or (0.0, 0.0)
        return f'{agreed} of {len(sets)} ({100 * low:.0f}-{100 * high:.0f} %)'

    lines = []
    for study, pairs in tables.items():
        for arm in dict.fromkeys(row.arm for row, _ in pairs):
            rows = [row for row, _ in pairs if row.arm == arm]
            term = arm.split('@')[0].split('=')[0]
            seen = {row.key: named for row in rows
                    if (named := named_by_seed(study, row.key, results, seeds, False))}
            moved = list(seen.values())
            kept = [named for named in (named_by_seed(study, row.key, results, seeds, True)
                                        for row in rows) if named is not None]
            by_seed = ', '.join(str(sum(term in named[shift] for named in moved))
                                for shift in range(seeds + 1))
            as_study = sum(seen[row.key][0] == tuple(row.outcome.named) for row in rows
                           if row.key in seen)
            lines.append(f'| {study} | {arm} | {same(moved)} | '
                         f'{same(kept) if kept else "-"} | {by_seed} | '
                         f'{as_study} of {len(moved)} |')
    return lines


def report(tables: dict[str, list[tuple[Any, Any]]], results: dict[Job, Diagnosed],
           seeds: int) -> None:
    """Print the agreement per study arm and every data set whose named terms changed."""
    print(f"\nNamed terms on the same runs at the study's seed and with it moved by 1..{seeds}"
          ' (split and simulations drawn again; with the split kept: the simulations alone):\n')
    print('| study | arm | same at every seed (95 %) | same, split kept (95 %) | named the '
          'term, by seed | first seed as in the study |')
    print('| --- | --- | --- | --- | --- | --- |')
    for line in agreement_rows(tables, results, seeds):
        print(line)
    changed = []
    for study, pairs in tables.items():
        for row, _ in pairs:
            for keep_split in (False, True):
                named = named_by_seed(study, row.key, results, seeds, keep_split)
                if named is not None and len(set(named)) > 1:
                    changed.append((study, row.key, keep_split, named))
    if changed:
        print('\nData sets whose named terms changed with the seed (study seed | moved):\n')
        for study, key, keep_split, named in changed:
            shown = ' | '.join(', '.join(terms) or 'nothing' for terms in named)
            print(f'- {study} {key}{" (split kept)" if keep_split else ""}: {shown}')
    cpu = sorted(result.cpu_s for result in results.values())
    commits = sorted({result.commit for result in results.values()})
    print(f'\n{len(cpu)} diagnoses at commit {", ".join(commits)}, {sum(cpu) / 60:.1f} CPU '
          f'minutes (median {cpu[len(cpu) // 2]:.0f} s each)')


def commit_here() -> str:
    """Return the checkout's commit, marked where the package differs from it."""
    def git(*args: str) -> str:
        return subprocess.run(['git', *args], cwd=REPO, capture_output=True, text=True,
                              check=False).stdout.strip()

    dirty = git('status', '--porcelain', '--', 'octoroach_model')
    return (git('rev-parse', '--short', 'HEAD') or 'unknown') + ('+changes' if dirty else '')


def main() -> int:
    """Diagnose every chosen data set at each seed, side by side, and print the agreement."""
    from concurrent.futures import as_completed

    from octoroach_model.workers import process_pool

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--studies', nargs='+', default=['periodic_limits', 'mixture_limits'])
    parser.add_argument('--arms', nargs='+', default=['@1x', '@+-1x'],
                        help='keep the data sets whose key contains one of these')
    parser.add_argument('--seeds', type=int, default=1, metavar='K',
                        help="seeds beyond the study's: the seed moved by 1..K")
    parser.add_argument('--keep-split', action='store_true',
                        help='also move the seed with the halves kept (the simulations alone)')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--results', type=Path, default=RESULTS)
    parser.add_argument('--again', action='store_true', help='rerun jobs already in results')
    parser.add_argument('--report-only', action='store_true')
    args = parser.parse_args()
    if args.results.is_symlink():
        raise SystemExit(f'{args.results} is a symbolic link: name the file itself')
    tables = {study: study_rows(study, args.arms) for study in args.studies}
    results = {} if args.again else read_results(args.results)
    if not args.report_only:
        nulls = {(study, row.key): null for study, pairs in tables.items()
                 for row, null in pairs}
        jobs = [Job(study, row.key, shift, keep)
                for study, pairs in tables.items() for row, _ in pairs
                for shift in range(args.seeds + 1)
                for keep in ((False, True) if args.keep_split and shift else (False,))]
        jobs = [job for job in jobs if job not in results]
        print(f'{len(jobs)} diagnoses to run ({len(results)} in {args.results}), '
              f'{args.workers} processes', flush=True)
        args.results.parent.mkdir(parents=True, exist_ok=True)
        commit = commit_here()
        with process_pool(args.workers, command=True) as pool:
            futures = [pool.submit(diagnosed, job, nulls[(job.study, job.key)], commit)
                       for job in jobs]
            for done, future in enumerate(as_completed(futures), 1):
                result = future.result()
                append_result(args.results, result)
                results[result.job] = result
                job = result.job
                print(f'[{done}/{len(jobs)}] {job.study} {job.key} seed +{job.shift}'
                      f'{" (split kept)" if job.keep_split else ""}: '
                      f'{", ".join(result.named) or "nothing"} ({result.cpu_s:.0f} s)',
                      flush=True)
    missing = [study for study, pairs in tables.items() for row, _ in pairs
               for shift in range(args.seeds + 1)
               if Job(study, row.key, shift, False) not in results]
    if missing:
        print(f'{len(missing)} diagnoses missing: run without --report-only')
        return 1
    report(tables, results, args.seeds)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
