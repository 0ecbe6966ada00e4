"""OceanWATERS' DockIngestSample action: the regolith in the sample dock is ingested (rospy
wiring only; the antenna mast node serves it, the simulation ingests: ``/sim/ingest_sample``)."""

from __future__ import annotations

from typing import Any

import rospy

from ow_lander.msg import DockIngestSampleAction, DockIngestSampleResult
from ow_msgs.srv import IngestSample
from ow_runtime.action_server import SimpleActionServer
from ow_runtime.names import SIM_INGEST_SAMPLE

#: OceanWATERS' status texts of DockIngestSample (HEAD's ow_lander actions.py).
INGESTED_TEXT = "Sample ingested"
NO_SAMPLE_TEXT = "No sample was present in dock"
SERVICE_FAILED_TEXT = "Removal service failed"
#: s of wall time a goal waits for the simulation's ingestion service (OceanWATERS: 10 s for
#: its removal service).
SERVICE_WAIT_S = 10.0


class DockIngestServer:
    """OceanWATERS' ``DockIngestSample`` (ow_lander/DockIngestSampleAction): the simulation
    ingests the regolith lying in the sample dock (``/sim/ingest_sample``, ow_msgs/IngestSample;
    the budget's ``in_dock`` becomes ``ingested`` and ``/ground_truth/material_ingested`` gets
    its ow_materials/BulkExcavation, docs/regolith.md). Ends SUCCEEDED "Sample ingested"
    (``sample_ingested`` true) or "No sample was present in dock" (false), as OceanWATERS;
    ABORTED "Removal service failed: <why>" (``sample_ingested`` false) when the service is not
    there within 10 s of wall time or fails. No fault group (as OceanWATERS), no feedback, and a
    cancel does not stop it (it ends at once). Unlike OceanWATERS, which removes the dock's
    particles at 1 Hz until none came for 3 s, the ingestion is one call: the regolith poured
    into the dock is there already.
    """

    def __init__(self) -> None:
        self._ingest = rospy.ServiceProxy(SIM_INGEST_SAMPLE, IngestSample)
        self.server = SimpleActionServer("DockIngestSample", DockIngestSampleAction, self._on_goal)
        self.server.start()

    def _on_goal(self, _: Any) -> None:
        try:
            self._ingest.wait_for_service(SERVICE_WAIT_S)
            response = self._ingest()
        except (rospy.ROSException, rospy.ServiceException) as error:
            self._abort(f"{SIM_INGEST_SAMPLE} did not answer: {error}")
            return
        if not response.success:
            self._abort(response.message)
            return
        text = INGESTED_TEXT if response.sample_ingested else NO_SAMPLE_TEXT
        self.server.set_succeeded(DockIngestSampleResult(response.sample_ingested), text)

    def _abort(self, why: str) -> None:
        rospy.logwarn(f"DockIngestSample: {why}")
        text = f"{SERVICE_FAILED_TEXT}: {why}"
        self.server.set_aborted(DockIngestSampleResult(sample_ingested=False), text)
