"""The names the camera node speaks (no rospy): OceanWATERS' topics, actions and parameters
(spec section 13). Consumers import them from here; those the fault detector watches too are
ow_runtime.names' (ow_faults cannot import ow_cameras).
"""

from ow_runtime.names import STEREO_LEFT_IMAGE_RAW, STEREO_LEFT_TRIGGER

#: The stereo camera's namespace (OceanWATERS' ``cameraName``).
CAMERA_NAMESPACE = "/StereoCamera"
#: std_msgs/Empty: a capture of both cameras (CameraCapture publishes here; anyone may).
LEFT_TRIGGER = STEREO_LEFT_TRIGGER
#: sensor_msgs/Image (rgb8) and CameraInfo of each camera, as Gazebo's triggered multicamera
#: publishes them (both with frame_id StereoCameraLeft_optical_frame, as OceanWATERS').
LEFT_IMAGE_RAW = STEREO_LEFT_IMAGE_RAW
LEFT_CAMERA_INFO = f"{CAMERA_NAMESPACE}/left/camera_info"
RIGHT_IMAGE_RAW = f"{CAMERA_NAMESPACE}/right/image_raw"
RIGHT_CAMERA_INFO = f"{CAMERA_NAMESPACE}/right/camera_info"
#: sensor_msgs/Image (rgb8), rectified (what stereo_image_proc publishes; ow_autonomy's
#: IdentifySampleLocation synchronizes the left one with the points, stamp for stamp).
LEFT_IMAGE_RECT_COLOR = f"{CAMERA_NAMESPACE}/left/image_rect_color"
RIGHT_IMAGE_RECT_COLOR = f"{CAMERA_NAMESPACE}/right/image_rect_color"
#: sensor_msgs/PointCloud2: organised (height x width), x y z rgb, left optical frame, m.
POINTS2 = f"{CAMERA_NAMESPACE}/points2"
#: std_msgs/Float64: s, exposure (OceanWATERS' CameraSetExposure publishes here; the node
#: follows it too).
EXPOSURE_TOPIC = "/gazebo/plugins/camera_sim/exposure"
#: Parameters (0-1) mirroring the lights' intensities, as OceanWATERS' light plugin holds them.
LIGHT_PARAMS = {
    "left": "/OWLightControlPlugin/left_light",
    "right": "/OWLightControlPlugin/right_light",
}

#: The actions (owl_msgs), under these plain names.
CAMERA_CAPTURE = "CameraCapture"
CAMERA_SET_EXPOSURE = "CameraSetExposure"
LIGHT_SET_INTENSITY = "LightSetIntensity"

#: The /faults parameter of the left camera's trigger failure (OceanWATERS' cam_faults group).
LEFT_TRIGGER_FAILURE = "camera_left_trigger_failure"
