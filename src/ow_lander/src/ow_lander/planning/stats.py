"""What the planner did: counts that each of its parts adds to, for messages and benchmarks."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class PlanStats:
    """What the planner did, for messages and benchmarks.

    Attributes:
        direct_segments: free-space segments solved by the direct joint-space segment.
        rrt_segments: free-space segments solved by RRT*.
        rrt_iterations: RRT* iterations run in total.
        cartesian_waypoints: IK solutions computed along Cartesian lines.
    """

    direct_segments: int = 0
    rrt_segments: int = 0
    rrt_iterations: int = 0
    cartesian_waypoints: int = 0
