"""
The diagnosis report on disk: report.json, summary.md and the plots, written all at once.

The one place the report becomes JSON (`jsonio.dumps`, the package's one converter) and files
(`fileio`'s atomic writers).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from octoroach_model.diagnosis.records import DiagnosisReport
from octoroach_model.diagnosis.summary import summary_text
from octoroach_model.errors import ParameterError
from octoroach_model.fileio import atomic_directory, user_path, write_text_atomic
from octoroach_model.jsonio import dumps
from octoroach_model.paths import check_paths, Paths
from octoroach_model.settings import flag, shown


def write_report(report: DiagnosisReport, out_dir: Path | str, measured: Paths | None = None,
                 plots: bool = True) -> dict[str, Path]:
    """
    Write report.json, summary.md and (with `measured`) the PNG plots into out_dir.

    All at once: they are written into a temporary folder beside out_dir that then takes its
    name (`fileio.atomic_directory`), so an interrupted call leaves the whole report or
    nothing; out_dir must be new or an empty directory. A plot that cannot be drawn is said
    in summary.md, never at the cost of the report.
    """
    if not isinstance(report, DiagnosisReport):
        raise ParameterError(f'report must be a DiagnosisReport (om.diagnose returns one), got '
                             f'{shown(report)}')
    out = user_path(out_dir, 'the report folder')
    if measured is not None:
        check_paths(measured)
    plots = flag('plots', plots)
    with atomic_directory(out, what='report folder') as folder:
        written: dict[str, Any] = {'report': folder / 'report.json',
                                   'summary': folder / 'summary.md'}
        write_text_atomic(written['report'], dumps(report, indent=2) + '\n')
        drawn: dict[str, Path] = {}
        errors: dict[str, str] = {}
        if plots and measured is not None:
            from octoroach_model.diagnosis.plots import write_plots
            drawn, errors = write_plots(report, measured, folder)
            written.update(drawn)
        summary = summary_text(report, [path.name for path in drawn.values()])
        if errors:
            summary += '\n## Plots not drawn\n\n' + ''.join(
                f'- {name}: {reason}\n' for name, reason in errors.items())
        write_text_atomic(written['summary'], summary)
    return {name: out / Path(path).relative_to(folder) for name, path in written.items()}
