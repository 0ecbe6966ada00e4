"""Headless Bullet simulation of the OceanWATERS lander arm (replaces Gazebo).

The ROS-free core is :class:`ow_sim_bullet.sim_core.BulletSim`, which steps its parts
(:mod:`~ow_sim_bullet.joint_control`, :mod:`~ow_sim_bullet.tool_forces`,
:mod:`~ow_sim_bullet.tool_tracking`, :mod:`~ow_sim_bullet.carving`); the node's outputs and
simulation thread are pure too (:mod:`~ow_sim_bullet.outputs`, :mod:`~ow_sim_bullet.runner`);
the ROS wiring is :mod:`ow_sim_bullet.sim_node`.
"""
