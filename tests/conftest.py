"""Fixtures for the whole suite: the ROS harness of ow_mission.testing (ros_master, ros_stack)."""

pytest_plugins = ["ow_mission.testing"]
