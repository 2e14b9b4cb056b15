"""ROS 1 for navigation stacks: `dynabarn-ros` (bridge: the simulation side; node: the
rospy side, run by Debian's Python; nav_build and stacks: move_base built from source)."""

READY_WHEN = ("command", "subscribed")
"""When a stack counts as started (the bridge's boot ends): it sent a /cmd_vel after the
goal (started, planned and controlling), or it subscribed to the scan."""
