"""
Where a diagnosis spends its time: the wall time of each stage, as the caller waits for it.

The report carries them (`DiagnosisReport.stages_s`), so that a slow diagnosis says which
stage was slow on the user's own machine and data. Work handed to the pool runs beside the
stage that submitted it; its time shows in the stage that waits for its result.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import time

# The stages in their order (docs/report.md names them; the report test checks both)
STAGES = ('read', 'prepare', 'baseline', 'race', 'final_fit', 'adequacy', 'limits_and_validations',
          'redraws')


@dataclass
class StageClock:
    """Accumulate wall seconds per stage; `enter` closes the stage before it."""

    seconds: dict[str, float] = field(default_factory=dict)
    current: str | None = None
    since: float = 0.0

    def enter(self, stage: str) -> None:
        """Start `stage` now (a stage entered again adds to its time)."""
        now = time.monotonic()
        self.stop(now)
        self.current, self.since = stage, now

    def stop(self, now: float | None = None) -> dict[str, float]:
        """Close the current stage; return the seconds per stage, rounded to milliseconds."""
        now = time.monotonic() if now is None else now
        if self.current is not None:
            total = self.seconds.get(self.current, 0.0) + now - self.since
            self.seconds[self.current] = round(total, 3)
            self.current = None
        return dict(self.seconds)
