"""The training split: worlds drawn on the fly from Alg. 1 and 2, never an evaluation world.

`ProceduralWorlds` draws training world k of a run from the paper's generator (Alg. 2's
obstacle count, Alg. 1's trajectories) under one of the named profile sets (Table I's
`table1`, the release's measured `release2022`), on a Fig. 2 branch drawn uniformly
(as the 300 shipped worlds: a third easy, a third medium, a third hard). A tier's name
(`tier-dense`, `tier-fast`, `tier-mixed`, `tier-combined`) draws from its profile file
instead: its counts and motions, and its shapes and static field. The branch and
profile set come from `SeedSequence([TRAIN_SEED_BASE + seed, k])`; the world itself is
`generate_world(branch, profile set, base_seed=((TRAIN_SEED_BASE + seed) << 40) + (k << 8)
+ redraw)`: the shipped worlds use base seed 2022 and the release's were drawn by the
original generator, so no stream is shared. Every drawn world is also checked by content
(`worlds.fingerprint`) against the reserved fingerprints it is given (the environment
gives the shipped 300; `reserved_fingerprints` also reads imported folders): one that
coincided is redrawn. A run's worlds are the fingerprints it records in the
policy's `trained_on`, which the `dagger` planner refuses to be evaluated on.

`split="validation"` draws from another seed namespace (`VALIDATION_SEED_BASE`): the
learning curve's worlds, never trained on and never the evaluation sets.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dynabarn.errors import DynabarnError, unknown_choice
from dynabarn.mjcf import write_world
from dynabarn.worlds.fingerprint import world_fingerprint
from dynabarn.worlds.generate import N_WORLDS, generate_world
from dynabarn.worlds.profile_file import GenerationProfile
from dynabarn.worlds.profiles import PROFILE_SETS, get_profile_set

TRAIN_SEED_BASE = 3_000_000_000
"""Training worlds' base seeds start here (the shipped worlds' is 2022)."""
VALIDATION_SEED_BASE = 4_000_000_000
SPLITS = {"train": TRAIN_SEED_BASE, "validation": VALIDATION_SEED_BASE}
DEFAULT_PROFILE_SETS = ("table1", "release2022")
MAX_DRAWS = 100


@dataclass(frozen=True)
class DrawnWorld:
    index: int
    path: Path
    difficulty: str
    fingerprint: str
    profile_set: str


def reserved_fingerprints(folders: tuple[Path, ...] = ()) -> frozenset[str]:
    """Fingerprints of the shipped 300 and of every world in `folders` (index.json sets).
    The shipped ones by their place in the package, whatever `$DYNABARN_WORLDS` points at."""
    from dynabarn.mjcf import read_world
    from dynabarn.provenance import SHIPPED_WORLDS
    from dynabarn.worldset import entry_path, read_index

    out = set()
    for folder in (SHIPPED_WORLDS, *folders):
        root = Path(folder)
        for entry in read_index(root)["worlds"]:
            out.add(world_fingerprint(read_world(entry_path(root, entry))))
    return frozenset(out)


def training_profile(name: str) -> GenerationProfile:
    """What a split draws worlds from, by name: a profile set (the paper's cylinders in an
    open arena: `table1`, `release2022`, or one registered) or a tier's profile file (its
    counts, motions, shapes and static field: `tier-dense`, `tier-mixed`, ...). A tier's
    profile only: the worlds come from the split's own seeds, never the tier's."""
    from dynabarn.worlds.tiers import TIERS

    if name in TIERS:
        return TIERS[name].profile()
    if name not in PROFILE_SETS.names():  # the profile sets' own refusal would name only them
        raise DynabarnError(unknown_choice("profile set or tier", name, [*PROFILE_SETS.names(), *TIERS]))
    return GenerationProfile(get_profile_set(name))


def describe_split(split: str, seed: int, profile_sets: tuple[str, ...]) -> dict:
    """A split's description, as a policy trained on it records it."""
    return {
        "split": f"procedural-{split}",
        "generator": "dynabarn Alg. 1 and 2",
        "profile_sets": list(profile_sets),
        "base_seed": f"(({SPLITS[split]} + {seed}) << 40) + (k << 8) + redraw",
    }


class ProceduralWorlds:
    """Worlds of a split, written on demand into `cache_dir` (at most `keep` files kept)."""

    def __init__(
        self,
        cache_dir: Path,
        *,
        split: str = "train",
        seed: int = 0,
        profile_sets: tuple[str, ...] = DEFAULT_PROFILE_SETS,
        reserved: frozenset[str] = frozenset(),
        keep: int = 64,
    ) -> None:
        if split not in SPLITS:
            raise DynabarnError(f"split {split!r}: use {' or '.join(SPLITS)}")
        self.split, self.seed = split, int(seed)
        self.base = SPLITS[split] + self.seed
        self.profile_sets = tuple(profile_sets)
        self._profiles = {name: training_profile(name) for name in self.profile_sets}  # one line for a bad name
        self.cache_dir = Path(cache_dir)
        self.reserved = reserved
        self.keep = keep
        self._cache: OrderedDict[int, DrawnWorld] = OrderedDict()

    def describe(self) -> dict:
        """What a policy records of its training split (beside the fingerprints)."""
        return describe_split(self.split, self.seed, self.profile_sets)

    def paths(self) -> set[str]:
        """The world files on disk now (older ones are removed as new ones are drawn)."""
        return {str(d.path) for d in self._cache.values()}

    def _base_seed(self, k: int, attempt: int) -> int:
        # One integer per (split, seed, k, attempt), all far above the shipped worlds' 2022.
        return (self.base << 40) + (k << 8) + attempt

    def world(self, k: int) -> DrawnWorld:
        """Training world k (the same for the same split, seed and k, on any machine)."""
        if k in self._cache:
            self._cache.move_to_end(k)
            return self._cache[k]
        rng = np.random.default_rng(np.random.SeedSequence([self.base, k]))
        for attempt in range(MAX_DRAWS):
            branch_id = int(rng.integers(N_WORLDS))
            name = self.profile_sets[int(rng.integers(len(self.profile_sets)))]
            profile = self._profiles[name]
            spec = generate_world(
                branch_id,
                profile.profile_set,
                base_seed=self._base_seed(k, attempt),
                shapes=profile.shapes,
                static_field=profile.static_field,
            )
            fp = world_fingerprint(spec)
            if fp not in self.reserved:
                break
        else:  # pragma: no cover - needs 100 coincidences in a row
            raise DynabarnError(f"{self.split} world {k}: every draw coincided with a reserved world")
        path = self.cache_dir / f"{self.split}_{self.seed}_{k:07d}.xml"
        if not path.is_file():
            write_world(spec, path)
        drawn = DrawnWorld(k, path, spec.difficulty.value, fp, name)
        self._cache[k] = drawn
        while len(self._cache) > self.keep:
            old = self._cache.popitem(last=False)[1]
            old.path.unlink(missing_ok=True)
        return drawn
