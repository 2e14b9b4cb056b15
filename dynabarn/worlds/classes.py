"""The difficulty tree of the paper's Fig. 2: a world's obstacle-count class and motion class
give its difficulty (easy, medium, hard)."""

from __future__ import annotations

import enum


class Difficulty(enum.StrEnum):
    EASY = "easy"
    MEDIUM = "medium"
    HARD = "hard"


class CountClass(enum.StrEnum):
    """Fig. 2's obstacle-count branch: low (5-9), high (10-19); imported sets may have
    worlds outside both, and their class says so (Fig. 2 treats them as the nearer branch)."""

    BELOW_LOW = "below-low"
    LOW = "low"
    HIGH = "high"
    ABOVE_HIGH = "above-high"


class MotionClass(enum.StrEnum):
    EASY = "easy"
    HARD = "hard"


LOW_COUNT: tuple[int, int] = (5, 9)
HIGH_COUNT: tuple[int, int] = (10, 19)
"""Fig. 2's obstacle counts of the low and high branches (the paper's and the release's)."""


def count_class_of(
    n_obstacles: int, low: tuple[int, int] = LOW_COUNT, high: tuple[int, int] = HIGH_COUNT
) -> CountClass:
    """The count branch of a world with `n_obstacles` (outside both ranges: below-low or above-high)."""
    if n_obstacles < low[0]:
        return CountClass.BELOW_LOW
    if n_obstacles <= low[1]:
        return CountClass.LOW
    if n_obstacles <= high[1]:
        return CountClass.HIGH
    return CountClass.ABOVE_HIGH


def difficulty_of(count: CountClass, motion: MotionClass) -> Difficulty:
    """Fig. 2: low+easy = easy; low+hard or high+easy = medium; high+hard = hard. A count
    below the low range counts as low, one above the high range as high."""
    few = count in (CountClass.LOW, CountClass.BELOW_LOW)
    if few and motion is MotionClass.EASY:
        return Difficulty.EASY
    if not few and motion is MotionClass.HARD:
        return Difficulty.HARD
    return Difficulty.MEDIUM
