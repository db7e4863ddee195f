"""
The same decision with the simulations drawn again: how much of it rests on their draws.

Everything a diagnosis decides from is partly simulated: the mean paths the geometry is fitted
to, the lines sizes are read off, the runs the held-out half is scored against. On the same
measured runs, another draw of those simulations can change a decision that sits near its
threshold: at a detection limit, a study's data sets named the same terms at two seeds, the
halves kept, on 7 of 11 (run_mixture) and 10 of 12 (heading_random_walk) (docs/measured.md,
"The same runs, another seed"). A decision that changes with the draw rests partly on it.

With `DiagnosisSettings.simulation_draws` K > 1, the diagnosis is made K - 1 more times on
the same halves (`split_seed` held at the report's), the simulations drawn from seed + 1, ...,
seed + K - 1, each the decision alone (diagnose.py's `redrawn_terms`: no adequacy check,
detection limits or validations, which name nothing), and the report says which terms each
draw named (`DrawAgreement`; diagnose.py's `redraw_settings` says how a draw is set). The
reported decision stays the first draw's: the others say how firmly it stands, they do not
vote.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from octoroach_model.jsonio import jsonable


@dataclass(frozen=True)
class DrawAgreement:
    """
    The terms each draw of the simulations named, on the same halves; the report's draw first.

    `seeds`: the simulations' seed of each draw; `split_seed`: the seed of the halves they
    share; `named`: each draw's named causes, then its extension terms.
    """

    seeds: tuple[int, ...]
    split_seed: int
    named: tuple[tuple[str, ...], ...]

    @property
    def same_as_reported(self) -> int:
        """Return how many draws named the same terms as the report (itself included)."""
        reported = set(self.named[0])
        return sum(set(terms) == reported for terms in self.named)

    @property
    def by_term(self) -> dict[str, int]:
        """Return, for every term some draw named, how many draws named it."""
        counts: dict[str, int] = {}
        for terms in self.named:
            for term in terms:
                counts[term] = counts.get(term, 0) + 1
        return counts

    def to_json(self) -> dict[str, Any]:
        plain: dict[str, Any] = jsonable({
            'count': len(self.seeds), 'seeds': self.seeds, 'split_seed': self.split_seed,
            'named': self.named, 'same_as_reported': self.same_as_reported,
            'by_term': self.by_term})
        return plain

    def sentence(self) -> str:
        """Say in words whether the decision stands whatever the draw (summary.md)."""
        draws = len(self.seeds)
        if self.same_as_reported == draws:
            return (f'The simulations, drawn {draws} times on the same halves, named the '
                    f'same terms every time ({draws} of {draws}): at this many draws, no sign '
                    'that the decision rests on them.')
        wavering = [f'{term} in {count}' for term, count in sorted(self.by_term.items())
                    if count < draws]
        return (f"**The decision rests partly on the simulations' draws**: of {draws} draws "
                f"on the same halves, {self.same_as_reported} (this report's included) named "
                f'the same terms as this report; named in only some of the {draws}: '
                f'{", ".join(wavering)}. Such a term sits near its threshold: more measured '
                'runs would settle it.')
