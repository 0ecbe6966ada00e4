"""``rosrun ow_mission monitors``: the stack's monitors as components of one node (rospy wiring
only): the power node, the battery, the OceanWATERS telemetry, the fault detector and the viz
node, and on request the ``/faults`` server and OceanWATERS' ``DockIngestSample``, each the class
its own node runs, with the same topics, services and parameters.

Each is a small loop over the same streams. As separate processes, each received and
deserialised every joint state again, and each paid the start-up of a Python process with rospy
and numpy; together they take each stream once (rospy keeps one connection per topic and
process), and the battery takes the power component's ``/power`` messages as they are published,
without a connection. The mission runs them so (docs/performance.md); ``rosrun ow_power power``
and the others still run each alone. The fault server is a component only when asked
(``~serve_faults``): a stack with a ``faults`` node of its own must not have two.

ROS API: the union of the components' (see each class), under this node's name:
    Parameters (private, read once): ``~power``, ``~battery``, ``~telemetry``, ``~viz``: each
        component's parameters, as its own node's private namespace (``node_config``).
        ``~serve_faults`` (bool, default false): also serve ``/faults`` (the ``faults`` node's
        services and topics), with ``~faults``: the faults injected from the start.
        ``~serve_dock_ingest`` (bool, default false): also serve the ``DockIngestSample``
        action (:class:`~ow_lander.mast.dock_ingest_node.DockIngestServer`, which the
        ``pan_tilt`` node serves in ``lander.launch``).
    Publishes: the viz markers as ``/viz/terrain``, ``/viz/tool_path``, ``/viz/ground_point``
        (where the viz node's ``~`` puts them).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Any

import rospy

from ow_bringup.errors import ConfigError
from ow_bringup.node_config import SERVE_DOCK_INGEST, SERVE_FAULTS
from ow_description.description import URDF_PATH
from ow_faults.detector_node import DetectorNode
from ow_faults.errors import FaultError
from ow_faults.faults_node import FaultsServer, hosted_server
from ow_lander import errors as lander_errors
from ow_lander.mast.dock_ingest_node import DockIngestServer
from ow_lander.telemetry.config import TelemetryConfig
from ow_lander.telemetry.node import TelemetryNode
from ow_power import errors as power_errors
from ow_power.battery_node import BatteryNode
from ow_power.config import BatteryConfig, PowerConfig
from ow_power.power_node import PowerNode
from ow_runtime.names import EVERY_MESSAGE, JOINT_STATES
from ow_runtime.node import init_node, spin
from ow_viz import errors as viz_errors
from ow_viz.config import VizConfig
from ow_viz.viz_node import VizNode

#: The components with parameters (private namespaces of this node).
CONFIGURED = ("power", "battery", "telemetry", "viz", "faults")
#: Topics a component takes every message of: rospy keeps one receive queue per topic in a
#: process, and the last ``queue_size`` given wins; checked once all are made.
EVERY_MESSAGE_TOPICS = (JOINT_STATES,)

ConfigErrors = (
    ConfigError,
    FaultError,
    lander_errors.ConfigError,
    power_errors.ConfigError,
    power_errors.PowerError,
    viz_errors.ConfigError,
    viz_errors.SceneError,
)


class Monitors:
    """The components, made in an order that leaves every shared topic unbounded: the viz
    (whose ``/joint_states`` queue is made unbounded too), the telemetry (a bounded queue of
    1000), the detector, the battery, then the power node (``/joint_states``: every message).
    The fault server, when asked, comes first.

    Args:
        params: component name -> its parameters (missing: the defaults).

    Raises:
        ConfigError: an unknown component, or (its package's class) a component's wrong
            parameters.
    """

    def __init__(self, params: Mapping[str, Mapping[str, Any]]) -> None:
        unknown = sorted(set(params) - {*CONFIGURED, SERVE_FAULTS, SERVE_DOCK_INGEST})
        if unknown:
            msg = f"monitors: unknown components {unknown}; known: {list(CONFIGURED)}"
            raise ConfigError(msg)
        for flag in (SERVE_FAULTS, SERVE_DOCK_INGEST):
            if not isinstance(params.get(flag, False), bool):
                msg = f"monitors: ~{flag} = {params[flag]!r} must be true or false"
                raise ConfigError(msg)
        serve = params.get(SERVE_FAULTS, False)
        if "faults" in params and not serve:
            msg = f"monitors: ~faults is given but ~{SERVE_FAULTS} is false"
            raise ConfigError(msg)
        viz = VizConfig.from_dict(params.get("viz", {}))
        telemetry = TelemetryConfig.from_dict(params.get("telemetry", {}))
        battery = BatteryConfig.from_dict(params.get("battery", {}))
        power = PowerConfig.from_dict(params.get("power", {}))
        self.faults: FaultsServer | None = None
        if serve:
            self.faults = hosted_server(params.get("faults", {}))
        self.viz = VizNode(viz, URDF_PATH.read_text(), "/viz/", EVERY_MESSAGE)
        self.telemetry = TelemetryNode(telemetry)
        self.detector = DetectorNode()
        # /power reaches the battery in this process: the topic's messages go out once, to
        # the other nodes, and are not serialised back to the node that made them.
        self.battery = BatteryNode(battery, subscribe=False, build_later=True)
        self.power = PowerNode(power, listeners=[self.battery.on_power])
        self.dock_ingest: DockIngestServer | None = None
        if params.get(SERVE_DOCK_INGEST, False):
            self.dock_ingest = DockIngestServer()
        manager = rospy.impl.registration.get_topic_manager()
        for topic in EVERY_MESSAGE_TOPICS:
            impl = manager.get_subscriber_impl(topic)
            if impl is not None and impl.queue_size is not None:
                msg = f"monitors: {topic} is received through a queue of {impl.queue_size}"
                raise RuntimeError(msg)


def main(argv: list[str] | None = None) -> int:
    """Run the monitors until shutdown; 1 on a configuration error."""
    init_node("monitors", argv=argv)
    try:
        monitors = Monitors(rospy.get_param("~", {}))
    except ConfigErrors as exc:
        rospy.logfatal(f"monitors: {exc}")
        return 1
    serving = " and the /faults server" if rospy.get_param(f"~{SERVE_FAULTS}", False) else ""
    rospy.loginfo(f"monitors: power, battery, telemetry, viz, the fault detector{serving} running")
    spin()
    return 1 if monitors.battery.failure else 0


if __name__ == "__main__":
    sys.exit(main())
