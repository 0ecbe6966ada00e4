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
#: The stereo camera's actions of OceanWATERS' CAMERA fault group (``rosrun ow_cameras camera``).
CAMERA_ACTIONS = ("CameraCapture", "CameraSetExposure")


# Topic and service names that more than one package speaks.

# ROS's conventional names, as the stack uses them.
CLOCK = "/clock"
JOINT_STATES = "/joint_states"
TF = "/tf"
TF_STATIC = "/tf_static"
ROBOT_DESCRIPTION = "/robot_description"

# OceanWATERS' telemetry and fault topics (owl_msgs), published by ow_lander's telemetry, ow_power's
# battery, ow_faults' detector and the simulation's wrist sensor.
ARM_JOINT_POSITIONS = "/arm_joint_positions"
ARM_JOINT_VELOCITIES = "/arm_joint_velocities"
ARM_JOINT_ACCELERATIONS = "/arm_joint_accelerations"
ARM_JOINT_TORQUES = "/arm_joint_torques"
ARM_POSE = "/arm_pose"
PAN_TILT_POSITION = "/pan_tilt_position"
ARM_END_EFFECTOR_FORCE_TORQUE = "/arm_end_effector_force_torque"
SYSTEM_FAULTS_STATUS = "/system_faults_status"
ARM_FAULTS_STATUS = "/arm_faults_status"
PAN_TILT_FAULTS_STATUS = "/pan_tilt_faults_status"
POWER_FAULTS_STATUS = "/power_faults_status"
CAMERA_FAULTS_STATUS = "/camera_faults_status"
#: The stereo camera's trigger (std_msgs/Empty) and left image (sensor_msgs/Image): the camera
#: node takes the one and publishes the other, the fault detector watches both.
STEREO_LEFT_TRIGGER = "/StereoCamera/left/image_trigger"
STEREO_LEFT_IMAGE_RAW = "/StereoCamera/left/image_raw"
BATTERY_STATE_OF_CHARGE = "/battery_state_of_charge"
BATTERY_REMAINING_USEFUL_LIFE = "/battery_remaining_useful_life"
BATTERY_TEMPERATURE = "/battery_temperature"

# The simulation's outputs other nodes read, and its clock services.
FLAGS_JOINT_STATES = "/flags/joint_states"
SIM_SCOOP_WRENCH = "/sim/scoop_wrench"
SIM_GRINDER_WRENCH = "/sim/grinder_wrench"
#: The scoop's terrain-force model state and wrench (ow_msgs/ToolState, geometry_msgs/
#: WrenchStamped, same stamp): with the live DEM, each pair one exchange.
SIM_SCOOP_MODEL_STATE = "/sim/scoop_model_state"
SIM_SCOOP_MODEL_WRENCH = "/sim/scoop_model_wrench"
#: Each dig of a live terrain-force model, when it ends or fails (ow_msgs/DemDig): its sample.
SIM_DEM_DIGS = "/sim/dem_digs"
#: The live DEM's digs stamped within a time window (ow_msgs/DemDigs; live DEM simulations only).
SIM_DEM_DIGS_SERVICE = "/sim/dem_digs_between"
SIM_RESUME = "/sim/resume"

# The regolith the simulation follows (ow_regolith in the sim node; docs/regolith.md).
#: Ingest what lies in the sample dock (ow_msgs/IngestSample); ow_lander's DockIngestSample.
SIM_INGEST_SAMPLE = f"{SIM_NAMESPACE}/ingest_sample"
#: The regolith budget (ow_msgs/RegolithBudget, latched), at each change.
REGOLITH_BUDGET = "/regolith/budget"
#: OceanWATERS' ground truth of each ingestion (ow_materials/BulkExcavation, latched).
MATERIAL_INGESTED = "/ground_truth/material_ingested"

# The arm services' outputs and services (rosrun ow_lander arm_services).
ARM_UNSTOW = "/arm/unstow"
ARM_OPERATION = "/arm/operation"
ARM_GROUND_DETECTOR = "/arm/ground_detector"
GUARDED_MOVE_RESULT = "/guarded_move_result"

# The power node's output (rosrun ow_power power) and the fault server (rosrun ow_faults faults).
POWER = "/power"
FAULTS = "/faults"
