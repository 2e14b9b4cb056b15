"""Tiers beyond the paper's hard (issue 43): named world sets, each drawn from a profile
file shipped with the package (`tier_profiles/`), its own base seed and the ids of the
paper's 60 (20 easy, 20 medium, 20 hard by Fig. 2's branches).

The definitions were committed before any planner ran on them, and no world is chosen,
dropped or redrawn because of a planner's result: only a world that is not certified
solvable for every trial (`dynabarn-worlds certify NAME --redraw`) is redrawn, from the
next seed of its own sequence; the draws and certificates are committed beside the
profile (`<profile>.certified.json`). `dynabarn-worlds generate --tier NAME`
(and `make worlds`) writes one to `generated_tiers/NAME/`; `--set NAME` runs it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from dynabarn.errors import WorldError
from dynabarn.registry import Registry, instances_of
from dynabarn.worlds.generate import PAPER60
from dynabarn.worlds.profile_file import GenerationProfile, read_profile_file

PROFILES_DIR = Path(__file__).resolve().parent / "tier_profiles"


@dataclass(frozen=True)
class Tier:
    """One tier: its profile file, its base seed and its world ids."""

    name: str
    profile_file: str
    """File name in `tier_profiles/`."""
    base_seed: int
    """Its own seed namespace: world i draws from SeedSequence([base_seed, i])."""
    ids: tuple[int, ...] = PAPER60

    def profile(self) -> GenerationProfile:
        return read_profile_file(PROFILES_DIR / self.profile_file)

    @property
    def certified_file(self) -> Path:
        """Its certificates, committed after `dynabarn-worlds certify NAME --redraw`."""
        return PROFILES_DIR / f"{Path(self.profile_file).stem}.certified.json"

    def certified(self) -> dict | None:
        """The committed certificates: {"draws": {id: k}, "certificates": {id: {protocol:
        record}}, "certification": {protocol: facts}}; None before the tier was certified."""
        try:
            return json.loads(self.certified_file.read_text())
        except FileNotFoundError:
            return None
        except (ValueError, UnicodeDecodeError) as exc:
            raise WorldError(f"{self.certified_file}: not valid JSON ({exc})") from None

    def draws(self) -> dict[int, int]:
        """{world id: k} for the worlds redrawn k times because a draw was not certified."""
        record = self.certified() or {}
        return {int(i): int(k) for i, k in record.get("draws", {}).items()}


TIERS: Registry[Tier] = Registry(
    "tier",
    {
        t.name: t
        for t in (
            Tier("tier-dense", "dense.toml", 4301),
            Tier("tier-fast", "fast.toml", 4302),
            Tier("tier-mixed", "mixed.toml", 4303),
            Tier("tier-combined", "combined.toml", 4304),
        )
    },
    error=WorldError,
    check=instances_of(Tier),
)
"""The tiers by name, easiest first (the seeds: issue 43, tier 1 to 4); `TIERS.register(Tier(...))`
adds one in this process (its profile and certificates beside the package's)."""


def get_tier(name: str | Tier) -> Tier:
    """The tier `name` (one line for an unknown name); a `Tier` is itself: resolved once
    where a command names it, then passed on."""
    return name if isinstance(name, Tier) else TIERS.get_item(name)
