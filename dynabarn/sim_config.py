"""Settings of the episode loop: physics step, control and pose rates, command limits."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynabarn.errors import DynabarnError

MAX_CLOCK_OFFSET = 5.0
"""Trials start the obstacles' clocks at a seeded offset in [0, 5) s."""


def episode_rng(seed: int) -> np.random.Generator:
    """A trial's random stream: its first draw is the clock offset, then the laser noise."""
    return np.random.default_rng(np.random.SeedSequence(seed))


def draw_clock_offset(rng: np.random.Generator) -> float:
    """The obstacles' clock offset [s]: the first draw of a trial's stream."""
    return float(rng.uniform(0.0, MAX_CLOCK_OFFSET))


def trial_clock_offset(seed: int) -> float:
    """The clock offset of trial `seed` [s], as its episode draws it (certificates use it)."""
    return draw_clock_offset(episode_rng(seed))


@dataclass(frozen=True, slots=True)
class SimConfig:
    """Settings of the episode loop.

    Attributes:
        dt: physics step [s] (<= 0.01: at 0.05 s a 2 m/s obstacle passes through the robot).
        control_rate: planner and scan rate [Hz]; the control period must be a whole
            number of physics steps.
        pose_rate: rate at which robot poses are handed to observers (and recorded) [Hz].
        max_linear_accel: |dv/dt| limit on the command [m/s^2] (jackal_control's
            diff-drive controller: linear.x.max_acceleration 20).
        max_angular_accel: |dw/dt| limit on the command [rad/s^2] (angular.z.max_acceleration 25).
    """

    dt: float = 0.005
    control_rate: float = 10.0
    pose_rate: float = 50.0
    max_linear_accel: float = 20.0
    max_angular_accel: float = 25.0

    def __post_init__(self) -> None:
        if not 1e-4 <= self.dt <= 0.01:  # also False for NaN
            raise DynabarnError(f"physics step dt must be in [0.0001, 0.01] s, got {self.dt}")
        for name in ("control_rate", "pose_rate"):
            if not 0.1 <= getattr(self, name) <= 1000.0:
                raise DynabarnError(f"{name} must be in [0.1, 1000] Hz, got {getattr(self, name)}")
        for name in ("max_linear_accel", "max_angular_accel"):
            if not 0 < getattr(self, name) <= 1e4:
                raise DynabarnError(f"{name} must be in (0, 10000], got {getattr(self, name)}")
        k = 1.0 / (self.control_rate * self.dt)
        if abs(k - round(k)) > 1e-6 or round(k) < 1:
            raise DynabarnError(
                f"the control period 1/{self.control_rate} s must be a whole number of physics steps of {self.dt} s"
            )

    @property
    def steps_per_tick(self) -> int:
        return round(1.0 / (self.control_rate * self.dt))

    @property
    def control_period(self) -> float:
        return self.steps_per_tick * self.dt

    @property
    def pose_every(self) -> int:
        return max(1, round(1.0 / (self.pose_rate * self.dt)))
