"""
Critical values for a decision taken again and again as runs arrive (anytime-valid).

A test repeated at every look finds an effect that is not there far more often than its
level says: a statistic that is a random walk under the null crosses a fixed z of 1.645
somewhere along 40 looks in about a quarter of the walks. The live decision
(`diagnosis/live.py`) therefore compares its two statistics with a boundary that holds over
every look at once, however many there are and whenever they are taken:

**The one-sided normal-mixture boundary** (Robbins 1970; Howard, Ramdas, McAuliffe and Sekhon
2021, "Time-uniform, nonparametric, nonasymptotic confidence sequences", Ann. Statist. 49(2),
section 3.3). Let S_V be a sum whose increments have mean mu and unit variance, V its
information (here: the runs in the half the statistic is taken on). For every lambda >= 0,
exp(lambda S_V - lambda^2 V / 2) is a supermartingale when mu <= 0; mixed over lambda with a
half-normal of precision rho,

    M_V = 2 sqrt(rho / (V + rho)) exp(S_V^2 / (2 (V + rho))) Phi(S_V / sqrt(V + rho)),

and Ville's inequality gives P(M_V >= 1 / alpha for some V) <= alpha. So the boundary is the
S where M_V = 1 / alpha; as a z statistic (S / sqrt(V)) it is `Boundary.z`. rho sets where the
boundary is tightest; it is chosen once, before any data, to minimise the boundary at the
information a session is planned to reach (`planned`, default PLANNED_RUNS runs in all).
Our statistics are estimates whose errors are estimated too, so the guarantee is
asymptotic (Waudby-Smith, Arbour, Sinha, Kennedy and Ramdas 2024, "Time-uniform central limit
theory and asymptotic confidence sequences", Ann. Statist. 52(6)); `studies/looks.py` measures
it through the whole procedure (README, "Deciding while the runs come in").

The same decision taken with a fixed z at every look (`Boundary(alpha, anytime=False)`) is
what a fixed-sample test repeated at each look does; the study prints both.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math

from scipy import optimize, stats

PLANNED_RUNS = 500        # the runs a session is planned to reach (the paper's 495)


@dataclass(frozen=True)
class Boundary:
    """
    The critical z of a one-sided test at level `alpha`, for a look at information V.

    `anytime`: the normal-mixture boundary, valid over every look at once (module
    docstring), tightest at information `planned`; otherwise the fixed-sample z at every
    look.
    """

    alpha: float
    anytime: bool = True
    planned: float = PLANNED_RUNS / 2

    def z(self, information: float) -> float:
        """Return the critical z at `information` (runs in the half the statistic uses)."""
        if not self.anytime:
            return float(stats.norm.isf(self.alpha))
        return mixture_z(max(float(information), 1.0), self.alpha, mixture_precision(
            self.alpha, self.planned))

    def p(self, information: float) -> float:
        """Return the one-sided p-value a fixed-sample test must beat at this look."""
        return float(stats.norm.sf(self.z(information)))


def mixture_z(information: float, alpha: float, precision: float) -> float:
    """Return z = S / sqrt(V) where the half-normal mixture M_V reaches 1 / alpha."""
    v, rho = information, precision
    total = v + rho

    def excess(s: float) -> float:
        # log M_V - log(1 / alpha), increasing in s
        return (math.log(2.0) + 0.5 * math.log(rho / total) + s * s / (2 * total)
                + float(stats.norm.logcdf(s / math.sqrt(total))) + math.log(alpha))

    high = math.sqrt(v) * 2.0 + 1.0
    while excess(high) < 0:
        high *= 2.0
    return float(optimize.brentq(excess, 0.0, high, xtol=1e-10)) / math.sqrt(v)


@lru_cache(maxsize=64)
def mixture_precision(alpha: float, planned: float) -> float:
    """Return the mixing precision rho that makes the boundary tightest at `planned`."""
    planned = max(float(planned), 1.0)
    found = optimize.minimize_scalar(
        lambda log_rho: mixture_z(planned, alpha, math.exp(log_rho)),
        bounds=(math.log(planned) - 12.0, math.log(planned) + 6.0), method='bounded',
        options={'xatol': 1e-4})
    return float(math.exp(found.x))


def two_sided_z(information: float, alpha: float, planned: float) -> float:
    """
    Return the half-width, in standard errors, of a 1 - alpha confidence sequence.

    Two one-sided boundaries at alpha / 2 each: the interval holds the truth at every look at
    once with probability at least 1 - alpha (module docstring).
    """
    return Boundary(alpha / 2, True, planned).z(information)
