"""The seed protocol: which episode seeds each use of a model may draw from.

An episode of ``env.reset(seed=s)`` is the same episode wherever it runs, so a seed that
chose a model (a checkpoint, a recipe, a run among candidates) no longer measures it
without bias. The seeds are therefore split into ranges, each for one use:

* :data:`TRAINING`, 0-999,999: ``srpb-gym train --seed`` (environment i of a run starts
  with seed + i, then continues its own generator stream);
* :data:`CHECKPOINT_SELECTION`, 1,000,000-1,999,999: the periodic evaluations of a run,
  which choose ``best/``;
* :data:`DEMONSTRATIONS`, 2,000,000-2,999,999: the demonstrations of a warm start (and its
  DAgger rounds);
* :data:`VALIDATION`, 3,000,000-3,999,999: every other choice (``training.ship
  --validate``, recipe comparisons, tuning, analyses that inform them);
* :data:`TEST`, 20,000,000-20,999,999: reports, never a choice: a shipped model's test
  figures, computed once, at shipping (``training.ship``), and the comparisons of
  finished recipes (``scripts/controlled_comparison.py``);
* :data:`RETIRED_TEST`, 10,000-10,999: the former test seeds. Evaluated for dozens of
  candidate models, they decided whether searches went on, so they are no longer held
  out; kept only to reproduce the figures of the cards shipped before (numerically they
  lie in the training range).

Selection code (periodic evaluation, validation, demonstrations, tuning) calls
:func:`check_not_test`, which refuses any seed of :data:`TEST` with an
:class:`~srpb_gym.errors.InputError` naming the option. Plain constants and small checks:
imports nothing but :mod:`srpb_gym.errors`.
"""

from __future__ import annotations

from dataclasses import dataclass

from srpb_gym.errors import InputError

__all__ = ["CHECKPOINT_SELECTION", "DEMONSTRATIONS", "RANGES", "RETIRED_TEST", "TEST",
           "TRAINING", "VALIDATION", "SeedRange", "check_not_test", "check_within",
           "range_of"]  # fmt: skip


@dataclass(frozen=True)
class SeedRange:
    """Seeds ``start`` to ``stop - 1`` of one use (``name``; ``users``: who may draw them)."""

    name: str
    start: int
    stop: int
    users: str

    @property
    def size(self) -> int:
        return self.stop - self.start

    def __contains__(self, seed: object) -> bool:
        return isinstance(seed, int) and self.start <= seed < self.stop

    def overlaps(self, first: int, count: int) -> bool:
        """Whether seeds ``first`` to ``first + count - 1`` meet this range."""
        return count > 0 and first < self.stop and first + count > self.start

    def holds(self, first: int, count: int) -> bool:
        """Whether seeds ``first`` to ``first + count - 1`` all lie in this range."""
        return self.start <= first and first + count <= self.stop

    def text(self) -> str:
        """``name (seeds start-last)``, as errors and cards name a range."""
        return f"{self.name} seeds ({self.start}-{self.stop - 1})"


TRAINING = SeedRange("training", 0, 1_000_000, "srpb-gym train --seed")
CHECKPOINT_SELECTION = SeedRange("checkpoint-selection", 1_000_000, 2_000_000,
                                 "the periodic evaluations of a run (best/)")  # fmt: skip
DEMONSTRATIONS = SeedRange("demonstration", 2_000_000, 3_000_000,
                           "the demonstrations of a warm start")  # fmt: skip
VALIDATION = SeedRange("validation", 3_000_000, 4_000_000,
                       "training.ship --validate, recipe comparisons, tuning")  # fmt: skip
TEST = SeedRange("test", 20_000_000, 21_000_000,
                 "training.ship: a shipped model's test figures, once")  # fmt: skip
RETIRED_TEST = SeedRange("retired test", 10_000, 11_000,
                         "nobody: reproducing the cards shipped before")  # fmt: skip
#: every range, the retired one last
RANGES = (TRAINING, CHECKPOINT_SELECTION, DEMONSTRATIONS, VALIDATION, TEST, RETIRED_TEST)


def range_of(seed: int) -> SeedRange | None:
    """The range that ``seed`` lies in (the retired test range before training, which
    holds it), or ``None``."""
    if seed in RETIRED_TEST:
        return RETIRED_TEST
    return next((r for r in RANGES if seed in r), None)


def check_not_test(first_seed: int, count: int, where: str) -> None:
    """Refuse seeds ``first_seed`` to ``first_seed + count - 1`` when any is a test seed:
    an :class:`InputError` naming the option ``where``. Everything that chooses (a
    checkpoint, a recipe, a run, a setting) calls it."""
    if TEST.overlaps(first_seed, count):
        last = first_seed + count - 1
        raise InputError(f"seeds {first_seed}-{last} meet the {TEST.text()}, which only "
                         f"measure a shipped model once; choose with the "
                         f"{VALIDATION.text()}", key=where)  # fmt: skip


def check_within(seeds: SeedRange, first_seed: int, count: int, where: str) -> None:
    """Refuse seeds ``first_seed`` to ``first_seed + count - 1`` that leave ``seeds``: an
    :class:`InputError` naming the option ``where``."""
    if not seeds.holds(first_seed, count):
        last = first_seed + count - 1
        raise InputError(f"seeds {first_seed}-{last} leave the {seeds.text()}", key=where)
