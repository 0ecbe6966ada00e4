"""Names and conventions every node of the stack shares: topic and service names that no single
producer owns, and how a subscriber asks for every message. No rospy."""

#: ``queue_size`` of a subscriber that must process every message (joint states for the power
#: integral and the arm's monitor, fault flags, ...): no receive limit. rospy drops all but the
#: newest ``queue_size`` messages of each socket read, and a node lagging a simulation that runs
#: many times faster than real time reads hundreds at once. rospy's -1 sets "no limit" even
#: where another subscriber of the topic in the process set one (None would leave that).
EVERY_MESSAGE = -1

#: s (sim), two stamps this close are the same instant: ROS stamps are whole nanoseconds, and a
#: stamp read as float seconds and written back can move by one.
STAMP_SLACK_S = 1e-6


# The simulation's clock protocol (the sim node, ``rosrun ow_sim_bullet sim``, serves it; the
# clients are ow_runtime.lockstep_client and ow_runtime.clock_client; docs/determinism.md).
#: The node's name: its private topics and services are ``/sim/<name>``.
SIM_NAMESPACE = "/sim"
#: The lockstep's acknowledgements (ow_msgs/LockstepAck), registration
#: (ow_msgs/LockstepRegister) and status (ow_msgs/LockstepStatus).
ACK_TOPIC = f"{SIM_NAMESPACE}/lockstep"
REGISTER_SERVICE = f"{SIM_NAMESPACE}/lockstep_register"
STATUS_SERVICE = f"{SIM_NAMESPACE}/lockstep_status"
#: The height map the simulation carves (ow_msgs/HeightMap, latched).
TERRAIN_TOPIC = f"{SIM_NAMESPACE}/terrain"
#: Timed trajectories for the arm (trajectory_msgs/JointTrajectory).
TRAJECTORY_TOPIC = f"{SIM_NAMESPACE}/joint_trajectory"
#: frame_id prefix of the receipt of a command (trajectory, set-point) the simulation ignored.
REFUSED = "refused:"
#: ``/sim/pause``'s message when the clock was stopped already.
ALREADY_PAUSED = "already paused"


# OceanWATERS' action servers (owl_msgs), served by ow_lander and ow_lander's mast.
#: The arm actions (``rosrun ow_lander arm_services`` serves each under this plain name).
ARM_ACTIONS = (
    "ArmUnstow",
    "ArmStow",
    "ArmMoveJoint",
    "ArmMoveJoints",
    "ArmMoveJointsGuarded",
    "ArmMoveCartesian",
    "ArmMoveCartesianGuarded",
    "ArmFindSurface",
    "TaskGrind",
    "TaskScoopCircular",
    "TaskScoopLinear",
    "TaskDeliverSample",
    "TaskDiscardSample",
)
#: The antenna mast's actions (``rosrun ow_lander pan_tilt``).
PAN_TILT_ACTIONS = ("PanTiltMoveJoints", "PanTiltMoveCartesian")
