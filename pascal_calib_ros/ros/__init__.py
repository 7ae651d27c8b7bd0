"""ROS 2 layer: thin nodes that convert messages and call the pure core."""
