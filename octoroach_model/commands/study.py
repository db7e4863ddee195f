"""`study`: the diagnosis's operating characteristics over the data sets a spec describes."""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time
from typing import Any, TextIO, TYPE_CHECKING

from octoroach_model.commands.common import add_workers_argument, finite_float, OneLineParser

if TYPE_CHECKING:
    from octoroach_model.studies.rows import StudyRow


class ProgressBar:
    """
    A progress bar over a known number of rows, on stderr.

    On a terminal it is redrawn in place; in a log (not a terminal) it writes one line per
    5 % step and one for the last row.
    """

    def __init__(self, label: str, stream: TextIO | None = None, width: int = 30) -> None:
        self.label, self.width = label, width
        self.stream = stream or sys.stderr
        self.live = self.stream.isatty()
        self.started = time.monotonic()
        self.first_done: int | None = None
        self.last_shown = -1.0

    def __call__(self, done: int, total: int, row: StudyRow | None = None) -> None:
        if self.first_done is None:
            self.first_done = done
        fraction = done / total if total else 1.0
        if not self.live and fraction - self.last_shown < 0.05 and done < total:
            return
        self.last_shown = fraction
        elapsed = time.monotonic() - self.started
        filled = int(round(fraction * self.width))
        bar = '#' * filled + '.' * (self.width - filled)
        computed = done - self.first_done
        left = ''
        if 0 < computed and done < total:
            left = f', about {elapsed / computed * (total - done) / 60:.1f} min left'
        last = f' last: {row.key} {row.status}' if row else ''
        text = (f'[{self.label} {bar}] {done}/{total} data sets, '
                f'{elapsed / 60:.1f} min{left}{last}')
        if self.live:
            self.stream.write('\r' + text[:200].ljust(120) + ('\n' if done >= total else ''))
        else:
            self.stream.write(text + '\n')
        self.stream.flush()


class DaskTlsFile(argparse.Action):
    """
    A --tls-* option: an existing file, put into dask's configuration for this process.

    Dask's `Security()` takes its certificates from `distributed.comm.tls` (what a lab's
    ~/.config/dask/distributed.yaml may hold too), so every Client this program makes to a
    `tls://` scheduler uses them, whichever command (study, plan) makes it.
    """

    KEYS = {'tls_ca_file': 'distributed.comm.tls.ca-file',
            'tls_cert': 'distributed.comm.tls.client.cert',
            'tls_key': 'distributed.comm.tls.client.key'}

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        import dask

        path = Path(str(values))
        if not path.is_file():
            parser.error(f'{option_string} {path}: no such file')
        setattr(namespace, self.dest, path)
        dask.config.set({self.KEYS[self.dest]: str(path.resolve()),
                         'distributed.comm.require-encryption': True})


def add_where_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the data sets are diagnosed: a Dask scheduler, local workers, or this process."""
    parser.add_argument('--scheduler', metavar='ADDRESS', default=None,
                        help='address of a running Dask scheduler (tls://host:8786 with the '
                        '--tls-* files; tcp:// only inside a trusted network) to send the '
                        'data sets to; default: a private local Dask cluster (TLS among its '
                        'own processes, no HTTP server)')
    parser.add_argument('--tls-ca-file', action=DaskTlsFile, default=None, metavar='PEM',
                        help="tls:// scheduler: the certificate authority of the cluster's "
                        'certificates')
    parser.add_argument('--tls-cert', action=DaskTlsFile, default=None, metavar='PEM',
                        help="tls:// scheduler: this client's certificate")
    parser.add_argument('--tls-key', action=DaskTlsFile, default=None, metavar='PEM',
                        help="tls:// scheduler: this client's private key")
    add_workers_argument(parser, 'the data sets (a local Dask cluster)')
    parser.add_argument('--connect-timeout-s', type=finite_float, default=10.0,
                        help='how long to wait for the scheduler to answer, s')


def parser() -> argparse.ArgumentParser:
    """Build the `study` command line."""
    result = OneLineParser(
        prog='study', description='Operating characteristics of the diagnosis: simulates the '
        'data sets SPEC describes (robots, causes and sizes, run counts, replicates), '
        'diagnoses each as a task on Dask, and writes DIR/table.csv (one row per data set, '
        'appended as rows arrive), DIR/summary.json (false-positive rate, power, estimation '
        'error, two-cause recovery, with 95 % intervals) and PNG plots. docs/studies.md '
        'describes the spec.')
    result.add_argument('spec', type=Path, metavar='SPEC.yaml', help='the study spec')
    result.add_argument('--out', type=Path, required=True, metavar='DIR',
                        help='directory for the results (new or empty, or with --resume the '
                        'directory of an interrupted study)')
    result.add_argument('--resume', action='store_true',
                        help='complete the study in DIR: keep its rows, compute the others '
                        '(the spec must be the one DIR was started with)')
    add_where_arguments(result)
    result.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    return result


def run(args: argparse.Namespace) -> int:
    """Run the study; prints where the table and the summary are."""
    from octoroach_model.studies import load_spec, run_study
    from octoroach_model.studies.table import TABLE_NAME

    spec = load_spec(args.spec)
    try:
        result = run_study(spec, args.out, scheduler=args.scheduler, workers=args.workers,
                           resume=args.resume, progress=ProgressBar('study'),
                           plots=not args.no_plots, connect_timeout_s=args.connect_timeout_s)
    except KeyboardInterrupt:
        sys.stderr.write(f'\nstudy: stopped; the finished rows are in '
                         f'{args.out / TABLE_NAME}; --resume completes the study\n')
        raise
    summary = result.summary
    problems = sum(count for status, count in summary.status.counts.items()
                   if status != 'ok')
    if problems:
        sys.stderr.write(f'study: {problems} of {result.rows} data sets have no diagnosis '
                         f'(status and note in the table)\n')
    rate = summary.false_positive.overall
    if rate.trials and rate.interval is not None:
        low, high = rate.interval
        sys.stderr.write(f'false-positive rate: {rate.successes} of {rate.trials} null '
                         f'data sets ({low:.1%} - {high:.1%})\n')
    print(f'table: {result.table}')
    print(f'summary: {result.summary_path}')
    for path in result.plots:
        print(f'plot: {path}')
    return 0
