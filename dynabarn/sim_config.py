"""Settings of the episode loop: physics step, control and pose rates, command limits."""

from __future__ import annotations

from dataclasses import Field, dataclass, field, fields

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


def _setting(default: float, low: float, high: float, unit: str, meaning: str, *, option: bool = False):
    """A `SimConfig` field with its range, unit and meaning declared once: the check here,
    the command-line options (`cli.common.add_sim_settings`: those with `option`) and the
    spec and the golden cases (`SimConfig` itself) all read it."""
    return field(default=default, metadata={"range": (low, high), "unit": unit, "meaning": meaning, "option": option})


@dataclass(frozen=True, slots=True)
class SimConfig:
    """Settings of the episode loop, each declared once with its range (`setting_ranges`).

    Attributes:
        dt: physics step [s] (<= 0.01: at 0.05 s a 2 m/s obstacle passes through the robot).
        control_rate: planner and scan rate [Hz]; the control period must be a whole
            number of physics steps.
        pose_rate: rate at which robot poses are handed to observers (and recorded) [Hz].
        max_linear_accel: |dv/dt| limit on the command [m/s^2] (jackal_control's
            diff-drive controller: linear.x.max_acceleration 20).
        max_angular_accel: |dw/dt| limit on the command [rad/s^2] (angular.z.max_acceleration 25).
    """

    dt: float = _setting(0.005, 1e-4, 0.01, "s", "physics step", option=True)
    control_rate: float = _setting(
        10.0, 0.1, 1000.0, "Hz", "planner and laser rate; 1/rate must be a whole number of --dt steps", option=True
    )
    pose_rate: float = _setting(50.0, 0.1, 1000.0, "Hz", "rate of the robot poses handed to observers")
    max_linear_accel: float = _setting(20.0, 1e-9, 1e4, "m/s^2", "|dv/dt| limit on the command")
    max_angular_accel: float = _setting(25.0, 1e-9, 1e4, "rad/s^2", "|dw/dt| limit on the command")

    def __post_init__(self) -> None:
        for f in fields(self):
            low, high = f.metadata["range"]
            value = getattr(self, f.name)
            if not low <= value <= high:  # also False for NaN
                raise DynabarnError(f"{f.name} must be in [{low:g}, {high:g}] {f.metadata['unit']}, got {value}")
        k = 1.0 / (self.control_rate * self.dt)
        if abs(k - round(k)) > 1e-6 or round(k) < 1:
            raise DynabarnError(
                f"the control period 1/{self.control_rate} s must be a whole number of physics steps of {self.dt} s"
            )

    def changed(self) -> dict[str, float]:
        """The settings that differ from the defaults (what a spec and a golden case carry)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) != f.default}

    @property
    def steps_per_tick(self) -> int:
        return round(1.0 / (self.control_rate * self.dt))

    @property
    def control_period(self) -> float:
        return self.steps_per_tick * self.dt

    @property
    def pose_every(self) -> int:
        return max(1, round(1.0 / (self.pose_rate * self.dt)))


def sim_options() -> tuple[Field, ...]:
    """The settings a command takes as options (`--dt`, `--control-rate`), each a `SimConfig`
    field with its default, range, unit and meaning in `metadata`."""
    return tuple(f for f in fields(SimConfig) if f.metadata["option"])
