"""The URDF as the simulation loads it: joint limits and damping, and inertias Bullet accepts."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ow_sim_bullet.errors import ConfigError


@dataclass(frozen=True)
class UrdfJoint:
    """One joint of the URDF.

    Attributes:
        name: joint name.
        kind: revolute, continuous, prismatic or fixed.
        parent: parent link.
        child: child link.
        effort_limit: N m (inf when not given).
        damping: N m s / rad, viscous joint damping.
    """

    name: str
    kind: str
    parent: str
    child: str
    effort_limit: float
    damping: float


def read_urdf_joints(urdf_text: str) -> dict[str, UrdfJoint]:
    """Joints of a URDF document by name, in document order.

    Args:
        urdf_text: the URDF document.

    Returns:
        joint name -> its type, links, effort limit and damping.

    Raises:
        ConfigError: a movable joint has a friction attribute (not simulated here).
    """
    joints = {}
    for element in ET.fromstring(urdf_text).iter("joint"):
        name = element.get("name", "")
        limit = element.find("limit")
        dynamics = element.find("dynamics")
        effort = float(limit.get("effort", "inf")) if limit is not None else math.inf
        damping = float(dynamics.get("damping", "0")) if dynamics is not None else 0.0
        if dynamics is not None and float(dynamics.get("friction", "0")) != 0.0:
            msg = f"URDF joint {name} has friction; joint friction is not simulated"
            raise ConfigError(msg)
        parent = element.find("parent")
        child = element.find("child")
        joints[name] = UrdfJoint(
            name,
            element.get("type", ""),
            parent.get("link", "") if parent is not None else "",
            child.get("link", "") if child is not None else "",
            effort,
            damping,
        )
    return joints


def physical_inertias(urdf_text: str, margin: float = 1e-3) -> tuple[str, list[str]]:
    """Make every inertia tensor satisfy the triangle inequality with a relative ``margin``.

    Bullet zeroes the inertia of a link whose principal moments (l1 <= l2 <= l3) break, or only
    just meet, l1 + l2 >= l3, which leaves the link without rotational inertia. Adding the
    smallest ``a`` times the identity (every principal moment grows by ``a``) restores it.

    Args:
        urdf_text: the URDF document.
        margin: required (l1 + l2 - l3) / l3.

    Returns:
        The (possibly) corrected URDF text and the names of the links that were corrected.
    """
    root = ET.fromstring(urdf_text)
    corrected = []
    for link in root.iter("link"):
        inertia = link.find("inertial/inertia")
        if inertia is None:
            continue
        names = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        ixx, ixy, ixz, iyy, iyz, izz = (float(inertia.get(k, "0")) for k in names)
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        low, mid, high = np.linalg.eigvalsh(tensor)
        shortfall = margin * high - (low + mid - high)
        if shortfall > 0:
            for key, value in (("ixx", ixx), ("iyy", iyy), ("izz", izz)):
                inertia.set(key, f"{value + shortfall:.9g}")
            corrected.append(link.get("name", ""))
    if not corrected:
        return urdf_text, []
    return ET.tostring(root, encoding="unicode"), corrected
