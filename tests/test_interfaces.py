"""The interface layer loads neither MuJoCo nor the simulator, and a planner, an observer,
an obstacle behaviour and a recording topic can be written against the package's face."""

from __future__ import annotations

import subprocess
import sys


def test_the_interfaces_load_without_mujoco_or_the_simulator():
    script = (
        "import sys\n"
        "from dynabarn.interfaces import EpisodeObserver, Observation, Planner\n"
        "loaded = sorted(m for m in sys.modules if m == 'mujoco' or m.startswith(('mujoco.', 'dynabarn.sim', "
        "'dynabarn.planners', 'dynabarn.worlds', 'scipy')))\n"
        "print(','.join(loaded) or 'none')\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "none"


def test_the_extension_types_are_on_the_package_face():
    import dynabarn
    from dynabarn.interfaces import EpisodeObserver, Planner
    from dynabarn.recording.topics import Topic
    from dynabarn.sim.behaviors import ObstacleBehavior

    assert dynabarn.Planner is Planner and dynabarn.EpisodeObserver is EpisodeObserver
    assert dynabarn.ObstacleBehavior is ObstacleBehavior and dynabarn.Topic is Topic


def test_an_observer_overrides_only_what_it_needs(tmp_path):
    """EpisodeObserver's hooks do nothing: an observer of ticks alone runs in an episode."""
    import dynabarn
    from dynabarn.interfaces import EpisodeObserver

    class CountTicks(EpisodeObserver):
        def __init__(self) -> None:
            self.ticks = 0

        def on_tick(self, tick) -> None:
            self.ticks += 1

    counter = CountTicks()
    spec = dynabarn.EpisodeSpec.make(dynabarn.resolve_world(137), "straight", dynabarn.get_protocol("barn"))
    result = dynabarn.run_spec(spec, observers=[counter]).result
    assert counter.ticks == result.n_ticks > 0
