"""YADE scenario script: settle a granular bed, or dig it with the scoop or the grinder.

Runs only inside YADE, as a subprocess (never imported by the ROS-free library)::

    yade -n -x -j1 yade_dig.py job.json

``job.json`` is written by :mod:`ow_dem_bridge.make_tables`; its keys are described in
:func:`main`. Two modes:

* ``settle``: rain a seeded cloud of spheres into a box and let it settle, then save the bed
  (``O.save``) so that every dig reloads the same bed (0.1 s instead of a settle per run).
* ``dig``: reload a bed, place the tool (thin plates of ``l_scoop`` or the stepped cylinder of
  ``l_grinder``, as facets, link-frame geometry taken from the URDF by the caller) just above the
  surface and move it kinematically through the reference motion. Every few steps one
  CSV row is written with the mean wrench of several reads, in the tool link frame, about the link
  centre of mass, while the tool tip is below the surface.

Scoop motion (paper Table 4): rotation of 90 deg at 30 deg/s, 0.3 m straight at 0.1 m/s, rotation
of 90 deg at 30 deg/s, about a pivot fixed in the scoop 0.36 m above its centre of mass
(OceanWATERS ROT_RADIUS). The air part of the first rotation is skipped, and the run stops as soon
as the tool is out of the bed. Grinder motion: axis vertical, plunge to the depth, then a straight
drag along the link +y axis.
"""

from __future__ import annotations

import csv
import json
import math
import random
import sys
import time
from typing import Any

from yade import O, geom, pack, utils
from yade._utils import sumForces, sumTorques
from yade.minieigenHP import Quaternion, Vector3
from yade.wrapper import (
    Bo1_Facet_Aabb,
    Bo1_Sphere_Aabb,
    ForceResetter,
    FrictMat,
    Ig2_Facet_Sphere_ScGeom6D,
    Ig2_Sphere_Sphere_ScGeom6D,
    InsertionSortCollider,
    InteractionLoop,
    Ip2_FrictMat_FrictMat_MindlinPhys,
    Law2_ScGeom_MindlinPhys_Mindlin,
    NewtonIntegrator,
    PyRunner,
    RotationEngine,
    Sphere,
    TranslationEngine,
)

#: Columns of the wrench in the samples CSV (tool link frame, torque about the link COM).
WRENCH_COLUMNS = ("Fx_N", "Fy_N", "Fz_N", "Tx_Nm", "Ty_Nm", "Tz_Nm")
Vec = Any  # a yade Vector3
Quat = Any  # a yade Quaternion


def shear_to_young(shear_modulus: float, poisson: float) -> float:
    """Pa, Young's modulus of an isotropic material from shear modulus (Pa) and Poisson ratio."""
    return 2.0 * shear_modulus * (1.0 + poisson)


def make_material(spec: dict[str, Any], label: str) -> int:
    """Add a Hertz-Mindlin material; return its id. ``spec`` keys: shear_modulus (Pa), poisson,
    static_friction, density (kg/m3)."""
    young = spec.get("young") or shear_to_young(spec["shear_modulus"], spec["poisson"])
    mat = FrictMat(
        young=young,
        poisson=spec["poisson"],
        frictionAngle=math.atan(spec["static_friction"]),
        density=spec["density"],
        label=label,
    )
    return int(O.materials.append(mat))


def rayleigh_time_step(radius: float, spec: dict[str, Any]) -> float:
    """s, Rayleigh time step of the smallest sphere (the usual Hertz-Mindlin stability bound)."""
    shear = spec["shear_modulus"]
    nu = spec["poisson"]
    return math.pi * radius * math.sqrt(spec["density"] / shear) / (0.1631 * nu + 0.8766)


def set_engines(job: dict[str, Any], gravity: float, damping: float) -> None:
    """Hertz-Mindlin contact with restitution and rolling friction (paper Table 5)."""
    soil = job["soil"]
    radius = job["particle_radius"]
    # Rolling stiffness after Ai et al. (2011), k_r = 2.25 k_n mu_r^2 R^2, with the Hertz normal
    # stiffness of two mean spheres at an overlap of 1e-3 R; the moment is capped at mu_r R F_n.
    young = shear_to_young(soil["shear_modulus"], soil["poisson"])
    e_star = young / (2.0 * (1.0 - soil["poisson"] ** 2))
    k_n = 2.0 * e_star * math.sqrt(0.5 * radius * 1e-3 * radius)
    k_rot = 2.25 * k_n * soil["rolling_friction"] ** 2 * radius**2
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb()], verletDist=0.1 * radius),
        InteractionLoop(
            [Ig2_Sphere_Sphere_ScGeom6D(), Ig2_Facet_Sphere_ScGeom6D()],
            [
                Ip2_FrictMat_FrictMat_MindlinPhys(
                    en=soil["restitution"],
                    es=soil["restitution"],
                    eta=soil["rolling_friction"],
                    krot=k_rot,
                )
            ],
            [Law2_ScGeom_MindlinPhys_Mindlin(includeMoment=True)],
        ),
        NewtonIntegrator(gravity=(0, 0, -gravity), damping=damping, label="newton"),
    ]
    O.dt = job["dt_safety"] * rayleigh_time_step(radius * (1.0 - job["radius_fuzz"]), soil)


def box_walls(length: float, width: float, height: float, wall_mat: int) -> list[int]:
    """Frictionless-enough container: bottom and four side walls as facets, open at the top."""
    walls = geom.facetBox(
        (length / 2, 0, height / 2),
        (length / 2, width / 2, height / 2),
        wallMask=31,
        material=wall_mat,
    )
    return [int(i) for i in O.bodies.append(walls)]


def surface_height(cell: float) -> float:
    """m, median over a grid of columns of the highest sphere top: the bed surface."""
    tops: dict[tuple[int, int], float] = {}
    for body in O.bodies:
        if not isinstance(body.shape, Sphere):
            continue
        key = (int(body.state.pos[0] // cell), int(body.state.pos[1] // cell))
        top = body.state.pos[2] + body.shape.radius
        tops[key] = max(tops.get(key, -1e9), top)
    values = sorted(tops.values())
    return values[len(values) // 2]


def settle(job: dict[str, Any]) -> dict[str, Any]:
    """Rain spheres into the bed box, settle them, save the bed; return a summary."""
    bed = job["bed"]
    soil_mat = make_material(job["soil"], "soil")
    # A frictionless container keeps the walls from carrying the bed's load.
    wall_mat = make_material({**job["tool_material"], "static_friction": 0.0}, "container")
    box_walls(bed["length"], bed["width"], bed["depth"] * 4.0, wall_mat)
    cloud = pack.SpherePack()
    radius = job["particle_radius"]
    # A loose cloud 3.5 bed depths high settles to more than one bed depth; the excess is cut.
    cloud.makeCloud(
        (radius, -bed["width"] / 2 + radius, radius),
        (bed["length"] - radius, bed["width"] / 2 - radius, 3.5 * bed["depth"]),
        rMean=radius,
        rRelFuzz=job["radius_fuzz"],
        seed=job["seed"],
    )
    cloud.toSimulation(material=soil_mat)
    # Settle fast under Earth gravity with damping; the dig runs switch to the job's gravity.
    set_engines(job, gravity=9.81, damping=0.4)
    while True:
        O.run(2000, True)
        if utils.unbalancedForce() < 0.01 or O.time > job["settle_time_max"]:
            break
    # Anything above the requested depth is removed, so every bed has a flat, known surface.
    cut = bed["depth"]
    for body in list(O.bodies):
        if isinstance(body.shape, Sphere) and body.state.pos[2] > cut:
            O.bodies.erase(body.id)
    for body in O.bodies:
        body.state.vel = Vector3.Zero
        body.state.angVel = Vector3.Zero
    O.run(200, True)
    O.save(job["bed_file"])
    n_spheres = sum(1 for b in O.bodies if isinstance(b.shape, Sphere))
    return {"spheres": n_spheres, "surface": surface_height(2 * radius), "sim_time": O.time}


def rot(axis: tuple[float, float, float], angle: float) -> Quat:
    """Quaternion of a rotation by ``angle`` rad about ``axis``."""
    return Quaternion(Vector3(*axis), angle)


class Tool:
    """The tool's facets and its rigid pose (link frame -> world).

    Attributes:
        tris: facet vertices in the link frame, m.
        com: link centre of mass in the link frame, m.
        tip: tip point in the link frame, m.
        ori: link orientation in the world.
        pos: link origin in the world, m.
        ids: body ids of the facets (after :meth:`spawn`).
    """

    def __init__(self, spec: dict[str, Any]) -> None:
        self.tris = [[Vector3(*v) for v in tri] for tri in spec["facets"]]
        self.com = Vector3(*spec["com"])
        self.tip = Vector3(*spec["tip"])
        self.ori = Quaternion.Identity
        self.pos = Vector3.Zero
        self.ids: list[int] = []

    def to_world(self, point: Vec) -> Vec:
        """World position of a link-frame point, m."""
        return self.pos + self.ori * point

    def lowest(self) -> float:
        """m, lowest world z of any facet vertex."""
        return min(self.to_world(v)[2] for tri in self.tris for v in tri)

    def rotate_about(self, pivot_world: Vec, q: Quat) -> None:
        """Rotate the pose by ``q`` about a world point."""
        self.pos = pivot_world + q * (self.pos - pivot_world)
        self.ori = q * self.ori

    def spawn(self, material: int) -> None:
        """Create the facets at the current pose; remove spheres that would overlap them."""
        self.ids = []
        for tri in self.tris:
            verts = [self.to_world(v) for v in tri]
            body = utils.facet(verts, material=material, fixed=True, wire=True)
            self.ids.append(int(O.bodies.append(body)))
        for body in list(O.bodies):
            if isinstance(body.shape, Sphere):
                for fid in self.ids:
                    if facet_distance(O.bodies[fid], body.state.pos) < body.shape.radius:
                        O.bodies.erase(body.id)
                        break


def facet_distance(facet_body: Any, point: Vec) -> float:
    """m, distance from a point to a facet triangle (exact, for the overlap check)."""
    verts = [facet_body.state.pos + facet_body.state.ori * v for v in facet_body.shape.vertices]
    a, b, c = verts
    ab, ac, ap = b - a, c - a, point - a
    d1, d2 = ab.dot(ap), ac.dot(ap)
    if d1 <= 0 and d2 <= 0:
        return (point - a).norm()
    bp = point - b
    d3, d4 = ab.dot(bp), ac.dot(bp)
    if d3 >= 0 and d4 <= d3:
        return (point - b).norm()
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return (point - (a + ab * (d1 / (d1 - d3)))).norm()
    cp = point - c
    d5, d6 = ab.dot(cp), ac.dot(cp)
    if d6 >= 0 and d5 <= d6:
        return (point - c).norm()
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return (point - (a + ac * (d2 / (d2 - d6)))).norm()
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return (point - (b + (c - b) * w)).norm()
    denom = 1.0 / (va + vb + vc)
    return (point - (a + ab * (vb * denom) + ac * (vc * denom))).norm()


class Recorder:
    """Reads the wrench on the tool every ``read_steps`` steps; writes the mean of
    ``reads_per_row`` reads as one CSV row while the tool tip is below the surface."""

    def __init__(self, tool: Tool, surface: float, out_path: str, job: dict[str, Any]) -> None:
        self.tool = tool
        self.surface = surface
        self.read_steps = int(job["read_steps"])
        self.reads_per_row = int(job["reads_per_row"])
        self.progress = 0.0
        self.max_depth = 0.0
        self.last_tip = tool.to_world(tool.tip)
        self.phase = ""
        self.acc = [0.0] * 6
        self.n = 0
        self.rows = 0
        self.file = open(out_path, "w", newline="")  # noqa: SIM115 - closed in close()
        self.writer = csv.writer(self.file)
        self.writer.writerow(["t_s", "phase", "depth_m", "progress_m", *WRENCH_COLUMNS])

    def read(self) -> None:
        """Called by a PyRunner after the integrator moved the tool."""
        tip = self.tool.to_world(self.tool.tip)
        depth = self.surface - tip[2]
        if depth > 0:
            self.progress += (tip - self.last_tip).norm()
        self.last_tip = tip
        if depth <= 0:
            return
        self.max_depth = max(self.max_depth, depth)
        com = self.tool.to_world(self.tool.com)
        inv = self.tool.ori.conjugate()
        ids = self.tool.ids
        axes = (Vector3.UnitX, Vector3.UnitY, Vector3.UnitZ)
        f_link = inv * Vector3(*(sumForces(ids, a) for a in axes))
        t_link = inv * Vector3(*(sumTorques(ids, a, com) for a in axes))
        for i in range(3):
            self.acc[i] += f_link[i]
            self.acc[3 + i] += t_link[i]
        self.n += 1
        if self.n >= self.reads_per_row:
            mean = [a / self.n for a in self.acc]
            self.writer.writerow(
                [f"{O.time:.5f}", self.phase, f"{depth:.6f}", f"{self.progress:.6f}"]
                + [f"{v:.6g}" for v in mean]
            )
            self.rows += 1
            self.acc = [0.0] * 6
            self.n = 0

    def close(self) -> None:
        """Flush and close the CSV."""
        self.file.close()


class Motion:
    """Moves the tool rigidly with YADE kinematic engines and keeps its analytic pose in step."""

    def __init__(self, tool: Tool, recorder: Recorder) -> None:
        self.tool = tool
        self.recorder = recorder
        self.velocity = Vector3.Zero
        self.omega = Vector3.Zero
        self.pivot = Vector3.Zero
        self.base = list(O.engines)
        self.engines: list[Any] = []

    def advance(self) -> None:
        """Follow the rigid motion over one PyRunner period, then read the wrench."""
        dt = O.dt * self.recorder.read_steps
        if self.omega.norm() > 0:
            q = Quaternion(self.omega.normalized(), self.omega.norm() * dt)
            self.tool.rotate_about(self.pivot, q)
        self.tool.pos = self.tool.pos + self.velocity * dt
        self.pivot = self.pivot + self.velocity * dt
        self.recorder.read()

    def phase(
        self,
        name: str,
        duration: float,
        velocity: Vec,
        omega: Vec,
        pivot: Vec,
        stop_when_out: float | None = None,
    ) -> None:
        """Move for ``duration`` s: translation ``velocity`` (m/s, world) and rotation ``omega``
        (rad/s, world) about ``pivot`` (world point, m). With ``stop_when_out`` (m), end the phase
        once the whole tool is that far above the surface."""
        self.recorder.phase = name
        self.velocity, self.omega, self.pivot = Vector3(velocity), Vector3(omega), Vector3(pivot)
        ids = self.tool.ids
        # Kinematic engines only set what they drive: a TranslationEngine leaves the angular
        # velocity of the previous rotation in place, and the facets would keep spinning.
        for i in ids:
            O.bodies[i].state.vel = Vector3.Zero
            O.bodies[i].state.angVel = Vector3.Zero
        engines: list[Any] = []
        if velocity.norm() > 0:
            engines.append(
                TranslationEngine(
                    ids=ids, translationAxis=velocity.normalized(), velocity=velocity.norm()
                )
            )
        if omega.norm() > 0:
            engines.append(
                RotationEngine(
                    ids=ids,
                    rotationAxis=omega.normalized(),
                    angularVelocity=omega.norm(),
                    rotateAroundZero=True,
                    zeroPoint=pivot,
                )
            )
        period = self.recorder.read_steps
        runner = PyRunner(iterPeriod=period, command="_ow_motion.advance()")
        globals()["_ow_motion"] = self
        # Kinematic engines before the integrator, the wrench reader after it.
        O.engines = [*self.base[:-1], *engines, self.base[-1], runner]
        steps = max(period, round(duration / O.dt / period) * period)
        chunk = 20 * period
        done = 0
        while done < steps:
            n = min(chunk, steps - done)
            O.run(n, True)
            done += n
            out = stop_when_out is not None and self.recorder.progress > 0
            if out and self.tool.lowest() > self.recorder.surface + (stop_when_out or 0.0):
                break


def dig(job: dict[str, Any]) -> dict[str, Any]:
    """Reload the bed, run the tool's motion, write the wrench samples; return a summary."""
    O.load(job["bed_file"])
    for eng in O.engines:
        if isinstance(eng, NewtonIntegrator):
            eng.gravity = (0, 0, -job["gravity"])
            eng.damping = 0.0
    tool_mat = make_material(job["tool_material"], "tool")
    radius = job["particle_radius"]
    surface = surface_height(2 * radius)
    depth = job["depth"]
    tool = Tool(job["tool"])
    motion = job["motion"]
    margin = 0.5 * radius
    zero = Vector3.Zero
    if job["tool"]["kind"] == "scoop":
        # Horizontal pose: link x forward (+x world), link z (the bottom's normal) down.
        tool.ori = rot((1, 0, 0), math.pi)
        tool.pos = Vector3(motion["x_cut"], 0, surface - depth) - tool.ori * tool.tip
        up = Vector3(0, 0, motion["pivot_height"])
        # Entry about a point above the tip: the tip (the lowest point) descends monotonically.
        pivot_in = tool.to_world(tool.tip) + up
        # Exit about a point above the back of the bottom: every point of the scoop rises.
        rear_x = min(v[0] for tri in tool.tris for v in tri)
        pivot_out_link = tool.ori.conjugate() * (
            tool.to_world(Vector3(rear_x, 0, tool.tip[2])) + up - tool.pos
        )
        rate = math.radians(motion["rotation_rate_deg"])
        omega = Vector3(0, -rate, 0)  # link x turns from pointing down towards forward
        full = math.radians(motion["rotation_deg"])
        start_ori, start_pos = tool.ori, tool.pos
        # Skip the part of the first rotation spent in the air.
        lo, hi = 0.0, full
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            tool.ori, tool.pos = start_ori, start_pos
            tool.rotate_about(pivot_in, rot((0, 1, 0), full - mid))
            if tool.lowest() > surface + margin:
                lo = mid
            else:
                hi = mid
        tool.ori, tool.pos = start_ori, start_pos
        tool.rotate_about(pivot_in, rot((0, 1, 0), full - lo))
        tool.spawn(tool_mat)
        recorder = Recorder(tool, surface, job["out_csv"], job)
        mover = Motion(tool, recorder)
        mover.phase("rotate_in", (full - lo) / rate, zero, omega, pivot_in)
        speed = motion["linear_speed"]
        mover.phase("linear", motion["linear_length"] / speed, Vector3(speed, 0, 0), zero, zero)
        pivot_out = tool.to_world(pivot_out_link)
        mover.phase("rotate_out", full / rate, zero, omega, pivot_out, stop_when_out=margin)
    else:
        # Grinder: link x (its axis) down, link y along the drag (+x world), link z = x cross y.
        tool.ori = rot((0, 1, 0), math.pi / 2) * rot((1, 0, 0), math.pi / 2)
        tool.pos = Vector3(motion["x_cut"], 0, 0) - tool.ori * tool.tip
        tool.pos = tool.pos + Vector3(0, 0, surface + margin - tool.lowest())
        tool.spawn(tool_mat)
        recorder = Recorder(tool, surface, job["out_csv"], job)
        mover = Motion(tool, recorder)
        plunge = motion["plunge_speed"]
        drop = tool.to_world(tool.tip)[2] - (surface - depth)
        mover.phase("plunge", drop / plunge, Vector3(0, 0, -plunge), zero, zero)
        speed = motion["linear_speed"]
        mover.phase("linear", motion["linear_length"] / speed, Vector3(speed, 0, 0), zero, zero)
    recorder.close()
    return {
        "surface": surface,
        "rows": recorder.rows,
        "progress": recorder.progress,
        "max_depth": recorder.max_depth,
        "sim_time": O.time,
        "dt": O.dt,
        "spheres": sum(1 for b in O.bodies if isinstance(b.shape, Sphere)),
    }


def main(argv: list[str]) -> int:
    """Run the job described by the JSON file ``argv[1]``; write its summary to ``job['summary']``.

    Job keys (SI units): mode ("settle" | "dig"), seed, soil and wall materials (shear_modulus Pa,
    poisson, static_friction, rolling_friction, restitution, density kg/m3), particle_radius m,
    radius_fuzz (relative), dt_safety (fraction of the Rayleigh step), bed {length, width, depth} m,
    bed_file, settle_time_max s, tool_material; for dig: gravity m/s2, depth m,
    tool {kind, facets, com, tip}, motion, read_steps, reads_per_row, out_csv.
    """
    with open(argv[1]) as fh:
        job = json.load(fh)
    random.seed(job["seed"])
    start = time.time()
    summary = settle(job) if job["mode"] == "settle" else dig(job)
    summary["wall_time_s"] = time.time() - start
    with open(job["summary"], "w") as fh:
        json.dump(summary, fh)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
