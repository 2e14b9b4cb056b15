"""The refusal check: a learned policy is never evaluated on a world it trained on.

A policy file records what it trained on (`trained_on`): the split (`procedural`: worlds
drawn on the fly from Alg. 1 and 2 under seeds of their own), its parameters, and the
fingerprint of every world it met (`dynabarn.worlds.fingerprint`). Before an episode the
planner compares the world's fingerprint (`EpisodeInfo.world_fingerprint`) with that
list and refuses with one line (exit 2) on a match, whatever the world file is called.
"""

from __future__ import annotations

from dynabarn.errors import DynabarnError


def trained_fingerprints(trained_on: dict) -> frozenset[str]:
    fps = trained_on.get("fingerprints", [])
    if not isinstance(fps, list) or not all(isinstance(f, str) for f in fps):
        raise DynabarnError("policy's trained_on.fingerprints is not a list of strings")
    return frozenset(fps)


def check_unseen(fingerprints: frozenset[str], world_fingerprint: str, policy: str) -> None:
    """Refuse (DynabarnError) when the episode's world is one the policy trained on."""
    if world_fingerprint and world_fingerprint in fingerprints:
        raise DynabarnError(
            f"policy {policy} trained on this world (fingerprint {world_fingerprint}): "
            "evaluate it on worlds it never saw"
        )
