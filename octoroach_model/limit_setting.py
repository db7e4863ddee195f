"""
Which detection limits a diagnosis computes: all, none, or those of the terms named.

The whole decision's limit of a term (diagnosis/limits.py) is most of a whole diagnosis's
time (docs/diagnosis.md, section 11) and decides nothing: a user with one question asks for
that term's alone. One `Setting` and one reader for `diagnose --limits` and the validator
node's `limits` parameter, which become `DiagnosisSettings.detection_limits` and
`limit_terms`; in a module of its own so that the node's parameters are declared without
loading the diagnosis (as redraw_setting.py).
"""
from __future__ import annotations

from collections.abc import Sequence

from octoroach_model.errors import ParameterError
from octoroach_model.model import EFFECT_NAMES
from octoroach_model.model.extensions import TERM_NAMES
from octoroach_model.settings import Setting, unknown_name

# the terms a diagnosis races: the table's causes, then the extension families' terms
# (diagnosis/causes.py's CANDIDATES, which asserts the two lists)
RACED_TERMS = (*EFFECT_NAMES, *TERM_NAMES)
LIMITS = Setting('the detection limits of the whole decision to compute: all, none (each '
                 "candidate then reports its size bound's own limit), or the terms named, "
                 'comma-separated (e.g. lateral_slip,speed_decay); they take most of a whole '
                 "diagnosis's time and the decision does not depend on them")


def check_term_names(names: Sequence[str], what: str) -> None:
    """Raise ParameterError, in one line, unless `names` are terms (`what` says where)."""
    if isinstance(names, str):
        raise ParameterError(f'{what} must be a list of terms, not one string')
    for name in names:
        if name not in RACED_TERMS:
            raise ParameterError(f'{what}: {unknown_name(name, RACED_TERMS)} is no term; give '
                                 'all, none or terms among ' + ', '.join(RACED_TERMS))


def read_limits(text: str) -> tuple[bool, tuple[str, ...]]:
    """Return (detection_limits, limit_terms) of 'all', 'none' or 'term,term,...'."""
    if text.strip() in ('all', 'none'):
        return text.strip() == 'all', ()
    terms = tuple(name.strip() for name in text.split(','))
    check_term_names(terms, 'limits')
    return True, terms
