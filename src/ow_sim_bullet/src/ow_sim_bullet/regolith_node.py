"""ROS wiring of the simulation's regolith (:mod:`ow_sim_bullet.regolith`, docs/regolith.md):
the budget's publisher, the ingestion service and its ground truth."""

from __future__ import annotations

import warnings
from typing import Any

import rospy

from ow_materials.msg import BulkExcavation
from ow_msgs.msg import DemDig, RegolithBudget
from ow_msgs.srv import DemDigs, DemDigsResponse, IngestSample, IngestSampleResponse
from ow_regolith.conversions import bulk_excavation
from ow_regolith.materials import Bulk
from ow_runtime.latched import latched_publisher
from ow_runtime.names import (
    MATERIAL_INGESTED,
    REGOLITH_BUDGET,
    SIM_DEM_DIGS,
    SIM_DEM_DIGS_SERVICE,
    SIM_INGEST_SAMPLE,
)
from ow_sim_bullet import conversions
from ow_sim_bullet.errors import SimError
from ow_sim_bullet.outputs import SimOutputs
from ow_sim_bullet.runner import SimRunner

#: The ingestion service's answer when the dock held nothing (OceanWATERS' DockIngestSample
#: text).
NO_SAMPLE = "No sample was present in dock"

#: Ingestions whose ground truth a slow subscriber may lag behind by (one message each).
_INGESTED_QUEUE = 10


class RegolithServer:
    """The regolith topics and service of the ``sim`` node.

    Publications:
        /regolith/budget (ow_msgs/RegolithBudget, latched): the six accounts (m^3, exactly in
            um^3, kg) by layer and material, from the start and at each change (at most once per
            carve update, and after an ingestion or a new terrain); stamp = sim time.
        /ground_truth/material_ingested (ow_materials/BulkExcavation, latched): OceanWATERS'
            ground truth of what one ingestion took from the dock: volume m^3 and composition by
            material; one message per ingestion that took something, stamp = its sim time.

    Services:
        /sim/ingest_sample (ow_msgs/IngestSample): ingest what lies in the sample dock (the
            budget's ``in_dock`` moves to ``ingested``): success with ``sample_ingested`` and
            ``volume`` m^3, or "No sample was present in dock" (``sample_ingested`` false);
            ``success`` false only when the simulation thread does not answer. ow_lander's
            DockIngestSample action calls it.

    Parameters: ``~regolith`` (:class:`ow_regolith.config.RegolithConfig`, docs/regolith.md).

    Args:
        runner: the simulation thread (the ingestion runs on it).
        outputs: the outputs, which publish the budget on :func:`budget_publisher`'s publisher.
    """

    def __init__(self, runner: SimRunner, outputs: SimOutputs) -> None:
        self._runner = runner
        self._outputs = outputs
        self._ingested = latched_publisher(
            MATERIAL_INGESTED, BulkExcavation, queue_size=_INGESTED_QUEUE
        )
        rospy.Service(SIM_INGEST_SAMPLE, IngestSample, self._on_ingest)

    def _ingest(self) -> tuple[float, Bulk]:
        """On the simulation thread: ingest the dock's content, publish the budget."""
        sim = self._runner.sim
        bulk = sim.regolith.ingest()
        self._outputs.publish_budget_if_changed()
        return sim.time, bulk

    def _on_ingest(self, _: Any) -> IngestSampleResponse:
        try:
            sim_time, bulk = self._runner.call(self._ingest)
        except SimError as error:
            return IngestSampleResponse(False, f"cannot ingest: {error}", False, 0.0)
        if bulk.is_empty:
            return IngestSampleResponse(True, NO_SAMPLE, False, 0.0)
        database = self._runner.sim.regolith.database
        self._ingested.publish(bulk_excavation(bulk, database, conversions.stamp(sim_time)))
        shares = ", ".join(
            f"{name} {float(share):.1%}" for name, share in bulk.composition().items()
        )
        text = f"ingested {bulk.volume_m3:.3g} m^3 ({bulk.mass_kg(database):.3g} kg: {shares})"
        return IngestSampleResponse(True, text, True, bulk.volume_m3)


def budget_publisher() -> rospy.Publisher:
    """The latched publisher of ``/regolith/budget``, writing on the simulation's thread: a
    subscriber that lags slows the simulation down instead of losing budgets (with rospy's
    queue of one, a loaded machine's recorder lost some, and two runs of one mission file had
    different streams)."""
    with warnings.catch_warnings():  # rospy warns of queue_size None
        warnings.simplefilter("ignore", SyntaxWarning)
        return latched_publisher(REGOLITH_BUDGET, RegolithBudget, queue_size=None)


def dem_digs_publisher() -> rospy.Publisher:
    """The publisher of ``/sim/dem_digs`` (ow_msgs/DemDig, one message per live DEM dig),
    writing on the simulation's thread: none is lost to a subscriber that lags."""
    with warnings.catch_warnings():  # rospy warns of queue_size None
        warnings.simplefilter("ignore", SyntaxWarning)
        return rospy.Publisher(SIM_DEM_DIGS, DemDig, queue_size=None)


class DemDigsServer:
    """``/sim/dem_digs_between`` (ow_msgs/DemDigs) of a live DEM simulation: its finished DEM
    digs (``BulletSim.finished_dem_digs``, as ``/sim/dem_digs`` published them) stamped within
    the request's window, read on the simulation thread: what it has learnt up to where it
    stands.

    Args:
        runner: the simulation thread.
    """

    def __init__(self, runner: SimRunner) -> None:
        self._runner = runner
        rospy.Service(SIM_DEM_DIGS_SERVICE, DemDigs, self._on_request)

    def _on_request(self, request: Any) -> DemDigsResponse:
        start, end = request.start.to_sec(), request.end.to_sec()

        def finished() -> list[tuple[float, dict[str, Any]]]:
            return list(self._runner.sim.finished_dem_digs)

        try:
            digs = [conversions.dem_dig_msg(t, "scoop", d) for t, d in self._runner.call(finished)]
        except SimError as error:
            raise rospy.ServiceException(str(error)) from error
        # By the stamps as published: the window's ends are stamps too.
        return DemDigsResponse([m for m in digs if start <= m.header.stamp.to_sec() <= end])
