"""
The design of a study: its tasks (one data set each) and what each replicate draws.

Seeding (docs/studies.md): replicate r of a study with seed S owns
`np.random.SeedSequence([S, r])`, whose children draw, in a fixed order, the robot, the data
seed, the damage and the signs of signed causes. Every arm and run count of replicate r uses
the same robot and the same data seed (common random numbers): the data sets of one replicate
differ only by the effects put into them, and (for the paper's model and most causes) a
smaller run count is the first runs of a larger one. Nothing depends on where or in which
order tasks run.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from octoroach_model.model import ModelParameters, nominal_sigmas
from octoroach_model.studies.spec import Arm, ArmKind, RobotSpec, StudySpec
from octoroach_model.studies.terms import TERMS

# children of a replicate's SeedSequence, in spawn order
ROBOT, DATA, DAMAGE, SIGNS = range(4)


@dataclass(frozen=True)
class Task:
    """
    One data set to simulate and diagnose: an arm at a run count for one replicate.

    `runs_cell` is the run count of the design (None where each replicate draws its own);
    `depends_on` is the key of the null task whose detection limits a relative arm reads.
    """

    key: str
    arm: Arm
    runs_cell: int | None
    replicate: int
    depends_on: str | None = None

    def runs(self, draw: RobotDraw) -> int:
        """Return the task's run count: its cell's, else the one its replicate drew."""
        runs = self.runs_cell if self.runs_cell is not None else draw.runs
        assert runs is not None, 'without run-count cells, every replicate draws its own count'
        return runs


@dataclass(frozen=True)
class RobotDraw:
    """The robot, run count and seeds one replicate drew."""

    replicate: int
    leg_length_cm: float
    hip_distance_cm: float
    touchdown_angles_deg: tuple[float, float, float, float]
    stride_frequency_hz: float
    cycles: float
    sample_rate_hz: float
    spread_scale: float
    runs: int | None              # drawn run count (None: the design's count is used)
    data_seed: int                # seed of the simulation and of the diagnosis

    def parameters(self) -> ModelParameters:
        """Return the model of this robot (liftoff angles by the paper's eqs. 7-8)."""
        phi1, phi2, phi3, phi4 = (math.radians(a) for a in self.touchdown_angles_deg)
        return replace(ModelParameters.nominal(), leg_length=self.leg_length_cm / 100,
                       hip_distance=self.hip_distance_cm / 100,
                       touchdown_angles=(phi1, phi2, phi3, phi4),
                       stride_frequency=self.stride_frequency_hz,
                       sample_rate=self.sample_rate_hz).with_paper_liftoff()

    @property
    def duration_s(self) -> float:
        """Return a run's duration: its cycles at the stride frequency."""
        return self.cycles / self.stride_frequency_hz

    def sigmas(self) -> tuple[float, float]:
        """Return (sigma1, sigma2) in rad: Table III times the spread scale."""
        sigma1, sigma2 = nominal_sigmas()
        return sigma1 * self.spread_scale, sigma2 * self.spread_scale


def replicate_seeds(spec_seed: int, replicate: int) -> list[np.random.SeedSequence]:
    """Return the 4 independent seed sequences of a replicate (robot, data, damage, signs)."""
    return np.random.SeedSequence([spec_seed, replicate]).spawn(4)


def draw_robot(spec: StudySpec, replicate: int) -> RobotDraw:
    """Draw replicate `replicate`'s robot: one uniform number per key, in a fixed order."""
    seeds = replicate_seeds(spec.seed, replicate)
    robot: RobotSpec = spec.robot
    u = np.random.default_rng(seeds[ROBOT]).random(len(RobotSpec.DRAWN) + 4 + 1)
    values = {name: getattr(robot, name).at(float(u[i]))
              for i, name in enumerate(RobotSpec.DRAWN)}
    offsets = [robot.touchdown_offset_deg.at(float(x)) for x in u[len(RobotSpec.DRAWN):-1]]
    phi1, phi2, phi3, phi4 = (base + offset
                              for base, offset in zip(robot.touchdown_angles_deg, offsets))
    runs = None if isinstance(spec.runs, tuple) else int(round(spec.runs.at(float(u[-1]))))
    data_seed = int(seeds[DATA].generate_state(1, np.uint32)[0])
    return RobotDraw(replicate, touchdown_angles_deg=(phi1, phi2, phi3, phi4), runs=runs,
                     data_seed=data_seed, **values)


def draw_signs(spec: StudySpec, replicate: int) -> dict[str, float]:
    """
    Draw +1 or -1 per term, for arms whose sign is 'both' (the same for every arm).

    The causes of the table come first, so their draws are those of studies run before the
    extension terms joined.
    """
    u = np.random.default_rng(replicate_seeds(spec.seed, replicate)[SIGNS]).random(len(TERMS))
    return {name: 1.0 if value < 0.5 else -1.0 for name, value in zip(TERMS, u)}


def task_key(arm: Arm, runs_cell: int | None, replicate: int) -> str:
    """Return a readable unique key: arm label, run count (n~ when drawn), replicate."""
    runs = f'n{runs_cell}' if runs_cell is not None else 'n~'
    return f'{arm.label}/{runs}/r{replicate}'


def build_tasks(spec: StudySpec) -> list[Task]:
    """
    List every task of the study in its canonical order (replicate, run count, arm).

    This is the order of the final table and the order in which tasks are handed out, so a
    study stopped early holds whole replicates.
    """
    null = next((arm for arm in spec.arms if arm.kind == ArmKind.NULL), None)
    tasks = []
    for replicate in range(spec.replicates):
        for cell in spec.run_cells:
            for arm in spec.arms:
                depends = task_key(null, cell, replicate) \
                    if arm.kind == ArmKind.RELATIVE and null is not None else None
                tasks.append(Task(task_key(arm, cell, replicate), arm, cell, replicate,
                                  depends))
    return tasks
