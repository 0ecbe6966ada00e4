"""Fixtures for the whole suite: the ROS harness of ow_bringup.testing (ros_master, ros_stack)."""

pytest_plugins = ["ow_bringup.testing"]
