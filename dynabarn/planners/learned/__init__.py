"""The learned baselines as planners (`bc`, `td3`): the Fig. 4 networks (models, needs
PyTorch), their observation and action (spaces, numpy only) and the planner (policy)."""

from dynabarn.planners.learned.policy import (
    SHIPPED,
    BCPlanner,
    DaggerPlanner,
    LearnedPlanner,
    PPOPlanner,
    TD3Planner,
)

__all__ = ["SHIPPED", "BCPlanner", "DaggerPlanner", "LearnedPlanner", "PPOPlanner", "TD3Planner"]
