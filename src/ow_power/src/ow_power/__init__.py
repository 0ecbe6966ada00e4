"""Arm power and energy (the paper's eqs. 1-4), bag recording and per-operation analysis.

The modules without ROS imports (:mod:`ow_power.model`, :mod:`ow_power.energy`,
:mod:`ow_power.bagwriter`, :mod:`ow_power.analysis`) work in any Python with numpy, pandas and
rosbags (:class:`ow_power.energy.ArmEnergyModel` also needs pinocchio and ``ow_lander``); the
``*_node`` modules are the thin rospy wrappers.
"""
