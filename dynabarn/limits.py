"""Bounds on what the commands and the training configurations accept, in one place (no
imports: the command-line parsers read them before anything heavy loads)."""

MAX_JOBS = 256
"""Parallel workers a command or a training run starts at most (each holds a MuJoCo model
and a planner)."""
MAX_SEED = 2**32 - 1
"""Largest trial (and training) seed."""
