"""ROS 1 for navigation stacks: `dynabarn-ros` (bridge: the simulation side; node: the
rospy side, run by Debian's Python)."""
