"""Headless Bullet simulation of the OceanWATERS lander arm (replaces Gazebo).

The ROS-free core is :class:`ow_sim_bullet.sim_core.BulletSim`; the node wiring is in
:mod:`ow_sim_bullet.sim_node`.
"""
