"""Learning: the Gymnasium environment `DynaBARN-v0` and its vector form, the procedural
training split, behaviour cloning, TD3 and DAgger.

Needs the optional extra (PyTorch and Gymnasium): `pip install 'dynabarn[learn]'`, or
`pip install -e '.[learn]'` in a checkout; only `configs` (the training commands'
settings) loads without it.
Importing this package registers the environment as `dynabarn/DynaBARN-v0` (and, as
before, `DynaBARN-v0`), with the protocol's longest episode as `max_episode_steps` and
`DynaBARNVectorEnv` as its vector entry point (`gymnasium.make_vec(...,
vectorization_mode="vector_entry_point")`).
"""

from __future__ import annotations

from dynabarn.errors import LEARN_EXTRA

try:
    import gymnasium
except ImportError:  # the extra is not installed: `configs` still loads (`dynabarn-train --help`)
    gymnasium = None

ENV_ID = "dynabarn/DynaBARN-v0"
ENV_IDS = (ENV_ID, "DynaBARN-v0")
"""The namespaced id, and the one of the first releases."""


def register_envs() -> None:
    """Register the environment ids with Gymnasium (idempotent)."""
    if gymnasium is None:
        raise ImportError(f"the DynaBARN-v0 environment needs {LEARN_EXTRA}")
    from dynabarn.learn.env import episode_step_limit

    for env_id in ENV_IDS:
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="dynabarn.learn.env:DynaBARNEnv",
                vector_entry_point="dynabarn.learn.vector_env:DynaBARNVectorEnv",
                max_episode_steps=episode_step_limit("barn"),
            )


if gymnasium is not None:
    register_envs()
