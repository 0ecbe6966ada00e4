"""The ``/faults`` server's change protocol, as its followers speak it (no rospy).

The server (``rosrun ow_faults faults``) publishes each change of its parameters on
:data:`CHANGES_TOPIC`, stamped with the sim time it holds from; every follower
(:class:`~ow_faults.change_follower_node.ChangeFollower`) applies it and answers on
:data:`APPLIED_TOPIC`. docs/faults.md and docs/determinism.md describe the exchange.
"""

#: The ``/faults`` server's changes, stamped with the sim time they hold from
#: (ow_msgs/FaultChange, latched).
CHANGES_TOPIC = "/faults/changes"
#: Each follower's word that it applied a change (ow_msgs/FaultChangeApplied).
APPLIED_TOPIC = "/faults/applied"
#: The ``/faults`` parameters whose name ends so lock joint ``j_<prefix>``.
LOCK_SUFFIX = "_joint_locked_failure"
