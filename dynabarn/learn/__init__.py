"""Learning: the Gymnasium environment `DynaBARN-v0`, behaviour cloning and TD3.

Needs the optional extra: `pip install -e '.[learn]'` (PyTorch, CPU, and Gymnasium).
Importing this package registers the environment.
"""

from __future__ import annotations

try:
    import gymnasium
except ImportError as exc:  # pragma: no cover - the extra is not installed
    raise ImportError("dynabarn.learn needs the learn extra: pip install -e '.[learn]'") from exc

ENV_ID = "DynaBARN-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="dynabarn.learn.env:DynaBARNEnv")
