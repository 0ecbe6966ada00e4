"""YADE worker of the live DEM: a particle bed that a tool digs in lockstep with the simulation.

Runs only inside YADE, as a subprocess of :class:`ow_dem_bridge.live.YadeWorker` (never imported
by the ROS-free library)::

    yade -n -x -j1 yade_live.py <request fd> <reply fd>

It reads one JSON request per line from the request pipe and writes one JSON reply per line to the
reply pipe (YADE's own banner and warnings go to stdout, which the caller sends to a log file).
Every reply has ``ok``; a failed request answers ``{"ok": false, "error": "..."}`` and the worker
goes on. End of file on the request pipe (the caller exited) ends the worker.

Requests (``op``), all lengths in m, times in s, in the *bed frame* (x along the dig, z up, origin
at the back of the bed on its floor; the caller transforms poses and velocities into it):

* ``template``: make (or reuse) the settled template bed: ``job`` is a settle job of
  :func:`yade_dig.settle` (its ``bed_file`` the cache file). A bed is settled once per material and
  size, saved to a temporary file and renamed, so that concurrent workers never read half a file,
  and every bed is then loaded from that file (the same state bit for bit). Answers its sphere
  count and its ``solid_fraction`` (:func:`solid_fraction`: spheres' volume over bulk volume).
* ``bed``: load the template, carve its surface down to the material's top (grid over the bed:
  ``u``, ``v`` axes, ``top[iv][iu]``, z of the loose layer's top where loose regolith lies on the
  solid surface ``h[iv][iu]``, else of that surface; ``top`` absent: ``h``), spawn the tool's
  facets (``tool``: link-frame ``facets``, ``com``) at ``pos`` / ``quat`` (w, x, y, z), remove
  the spheres they overlap, set gravity and the time step ``dt``; the wrench is read every
  ``read_steps`` DEM steps. Answers the particle count (``loose_particles`` of them with their
  centre above the solid surface: the loose layer, in the template's packing) and the DEM's time.
* ``step``: snap the tool to ``pos`` / ``quat``, move it rigidly for ``steps`` DEM steps with the
  link-origin velocity ``v`` (m/s) and angular velocity ``w`` (rad/s), and answer the mean wrench
  of the reads over those steps (N, N m; link frame at ``quat``, torque about the link COM), the
  fastest sphere's speed and the DEM time.
* ``glide``: move the tool from where it is to ``pos`` / ``quat`` at constant velocities over
  ``steps`` DEM steps, reading nothing: the simulation steps in which the tool was out of the
  ground (no exchange) still pass in the DEM, the tool moving as it moved.
* ``finish``: the sample: spheres whose centres lie in the tool's link-frame bounding box (count,
  the spheres' own volume m3, mass kg), and the bed's ``surface``: its bulk heights
  (:mod:`bed_surface`, the sample's spheres left out) minus those when the bed was made, per
  cell (``change[iv][iu]`` m, with the grid's ``length``, ``width``, ``nu``, ``nv``); the bed
  is kept until the next ``bed``.
* ``quit``: exit.
"""

from __future__ import annotations

import json
import math
import os
import sys
import traceback
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))

import bed_surface  # the sibling module: the bed's bulk heights (plain Python)
import yade_dig  # the sibling script: materials, engines, settling
from yade import O, utils
from yade._utils import sumForces, sumTorques
from yade.minieigenHP import Quaternion, Vector3
from yade.wrapper import PyRunner, Sphere

#: The facets' colour (utils.facet would draw a random one from Python's generator).
FACET_COLOR = (0.7, 0.7, 0.7)


class LiveTool:
    """The tool's facets, moved rigidly with the link pose the simulation sends.

    Attributes:
        ids: facet body ids.
        centres: each facet's body centre in the link frame.
        q0: the link orientation the facets were created at (their body orientation is identity
            there).
        com: link centre of mass, link frame.
        box: (lower, upper) corners of the facets' bounding box, link frame.
    """

    def __init__(self, spec: dict[str, Any], material: int, pos: Any, quat: Any) -> None:
        self.com = Vector3(*spec["com"])
        tris = [[Vector3(*v) for v in tri] for tri in spec["facets"]]
        lo = [min(v[i] for tri in tris for v in tri) for i in range(3)]
        hi = [max(v[i] for tri in tris for v in tri) for i in range(3)]
        self.box = (Vector3(*lo), Vector3(*hi))
        self.q0 = quat
        self.ids: list[int] = []
        self.centres = []
        for tri in tris:
            self.centres.append(utils.inscribedCircleCenter(tri[0], tri[1], tri[2]))
            world = [pos + quat * v for v in tri]
            body = utils.facet(world, material=material, fixed=True, color=FACET_COLOR)
            self.ids.append(int(O.bodies.append(body)))
        self.origin = Vector3(pos)
        self.quat = quat

    def snap(self, pos: Any, quat: Any, v: Any, w: Any) -> None:
        """Put the facets exactly at the link pose and give them the rigid velocity field."""
        turn = quat * self.q0.conjugate()
        for fid, centre in zip(self.ids, self.centres, strict=True):
            state = O.bodies[fid].state
            arm = quat * centre
            state.pos = pos + arm
            state.ori = turn
            state.vel = v + w.cross(arm)
            state.angVel = w
        self.origin = Vector3(pos)
        self.quat = quat

    def remove_overlaps(self) -> int:
        """Erase the spheres a facet overlaps (no spurious start-up force); how many."""
        corners = [
            O.bodies[fid].state.pos + O.bodies[fid].state.ori * v
            for fid in self.ids
            for v in O.bodies[fid].shape.vertices
        ]
        lo = [min(c[i] for c in corners) for i in range(3)]
        hi = [max(c[i] for c in corners) for i in range(3)]
        removed = 0
        for body in list(O.bodies):
            if not isinstance(body.shape, Sphere):
                continue
            pos, radius = body.state.pos, body.shape.radius
            if any(pos[i] < lo[i] - radius or pos[i] > hi[i] + radius for i in range(3)):
                continue  # clear of the tool's bounding box: no facet can touch it
            for fid in self.ids:
                if yade_dig.facet_distance(O.bodies[fid], body.state.pos) < body.shape.radius:
                    O.bodies.erase(body.id)
                    removed += 1
                    break
        return removed

    def contains(self, point: Any) -> bool:
        """Whether a world point lies in the tool's link-frame bounding box."""
        local = self.quat.conjugate() * (point - self.origin)
        lo, hi = self.box
        return all(lo[i] <= local[i] <= hi[i] for i in range(3))


class Reader:
    """Sums the force on the tool and its moment about the moving link origin every DEM step."""

    def __init__(self, tool: LiveTool) -> None:
        self.tool = tool
        self.velocity = Vector3.Zero
        self.origin = Vector3.Zero
        self.force = [0.0, 0.0, 0.0]
        self.moment = [0.0, 0.0, 0.0]
        self.count = 0
        self.recording = False
        self.start_origin = Vector3.Zero
        self.start_time = 0.0

    def start(self, origin: Any, velocity: Any, recording: bool) -> None:
        """Begin an exchange with the link origin at ``origin`` moving at ``velocity``."""
        self.origin, self.velocity, self.recording = Vector3(origin), Vector3(velocity), recording
        self.start_origin, self.start_time = Vector3(origin), O.time
        self.force = [0.0, 0.0, 0.0]
        self.moment = [0.0, 0.0, 0.0]
        self.count = 0

    def read(self) -> None:
        """Called by a PyRunner after the integrator, every ``read_steps`` DEM steps: this
        step's contact forces on the facets."""
        # The integrator has just moved the facets (their forces are this step's; the clock
        # ticks after the engines): the moment is taken about the link origin moved with them.
        self.origin = self.start_origin + self.velocity * (O.time + O.dt - self.start_time)
        if self.recording:
            ids = self.tool.ids
            axes = (Vector3.UnitX, Vector3.UnitY, Vector3.UnitZ)
            for i, axis in enumerate(axes):
                self.force[i] += sumForces(ids, axis)
                self.moment[i] += sumTorques(ids, axis, self.origin)
            self.count += 1


class Worker:
    """The worker's state: the template bed file, the tool, the reader."""

    def __init__(self) -> None:
        self.template: dict[str, Any] | None = None
        self.tool: LiveTool | None = None
        self.reader: Reader | None = None
        self.density = 0.0
        self.solid_fraction = 1.0
        self.grid: bed_surface.SurfaceGrid | None = None
        #: the bed's bulk heights when it was made (m, ``[iv][iu]``).
        self.heights_made: list[list[float]] = []

    # ------------------------------------------------------------------ requests
    def handle(self, request: dict[str, Any]) -> dict[str, Any]:
        """Answer one request."""
        op = request.get("op")
        if op == "template":
            return self.make_template(request["job"])
        if op == "bed":
            return self.make_bed(request)
        if op == "step":
            return self.step(request)
        if op == "glide":
            return self.glide(request)
        if op == "finish":
            return self.finish()
        msg = f"unknown request {op!r}"
        raise ValueError(msg)

    def make_template(self, job: dict[str, Any]) -> dict[str, Any]:
        """Settle the template bed once (cached in ``job['bed_file']``)."""
        path = job["bed_file"]
        cached = os.path.exists(path)
        if not cached:
            O.reset()
            partial = f"{path}.{os.getpid()}.partial.yade.gz"
            yade_dig.settle({**job, "bed_file": partial})
            os.replace(partial, path)
        self.template = job
        O.reset()
        O.load(path)
        spheres = sum(1 for b in O.bodies if isinstance(b.shape, Sphere))
        self.solid_fraction = solid_fraction(job)
        self.grid = bed_surface.SurfaceGrid.over_bed(
            job["bed"]["length"], job["bed"]["width"], job["particle_radius"]
        )
        return {
            "ok": True,
            "cached": cached,
            "template_spheres": spheres,
            "solid_fraction": self.solid_fraction,
        }

    def make_bed(self, request: dict[str, Any]) -> dict[str, Any]:
        """Load the template, carve it to the terrain, place the tool."""
        if self.template is None:
            msg = "no template bed: send 'template' first"
            raise RuntimeError(msg)
        job = self.template
        O.reset()
        O.load(job["bed_file"])
        yade_dig.set_engines(job, gravity=request["gravity"], damping=0.0)
        # The contact law (Mindlin, rolling moment from the relative angular velocity) reads
        # ScGeom's fields only: the sphere-sphere functor's relative rotations (twist, bending)
        # are never used, and not computing them gives the same forces bit for bit, ~7 % faster.
        O.engines[2].geomDispatcher.functors[0].updateRotations = False
        O.dt = request["dt"]
        self.density = job["soil"]["density"]
        us, vs, h = request["u"], request["v"], request["h"]
        surface = request.get("top", h)
        truncated = max(0.0, max(max(row) for row in surface) - job["bed"]["depth"])
        carved = loose = 0
        for body in list(O.bodies):
            if isinstance(body.shape, Sphere):
                pos = body.state.pos
                if pos[2] > bilinear(us, vs, surface, pos[0], pos[1]):
                    O.bodies.erase(body.id)
                    carved += 1
                elif surface is not h and pos[2] > bilinear(us, vs, h, pos[0], pos[1]):
                    loose += 1
        tool_mat = yade_dig.make_material(job["tool_material"], "tool")
        pos, quat = Vector3(*request["pos"]), Quaternion(*request["quat"])
        self.tool = LiveTool(request["tool"], tool_mat, pos, quat)
        overlaps = self.tool.remove_overlaps()
        self.reader = Reader(self.tool)
        globals()["_ow_live_reader"] = self.reader
        newton = O.engines[-1]
        O.engines = [
            *O.engines[:-1],
            newton,
            PyRunner(iterPeriod=int(request["read_steps"]), command="_ow_live_reader.read()"),
        ]
        O.dt = request["dt"]
        spheres = sum(1 for b in O.bodies if isinstance(b.shape, Sphere))
        self.heights_made = self.bulk_heights(None)
        return {
            "ok": True,
            "particles": spheres,
            "loose_particles": loose,
            "carved": carved,
            "overlaps_removed": overlaps,
            "truncated_m": truncated,
            "dt": O.dt,
            "time": O.time,
        }

    def step(self, request: dict[str, Any]) -> dict[str, Any]:
        """Move the tool for ``steps`` DEM steps; the mean wrench in the link frame."""
        tool, reader = self.tool, self.reader
        if tool is None or reader is None:
            msg = "no bed: send 'bed' first"
            raise RuntimeError(msg)
        pos, quat = Vector3(*request["pos"]), Quaternion(*request["quat"])
        v, w = Vector3(*request["v"]), Vector3(*request["w"])
        tool.snap(pos, quat, v, w)
        reader.start(pos, v, True)
        O.run(int(request["steps"]), True)
        reply = self.progress()
        n = max(reader.count, 1)
        inv = quat.conjugate()
        force = inv * Vector3(*(f / n for f in reader.force))
        moment_origin = inv * Vector3(*(m / n for m in reader.moment))
        # About the COM: M_com = M_origin - com x F (link frame, com from the origin).
        torque = moment_origin - tool.com.cross(force)
        reply["wrench"] = [float(force[i]) for i in range(3)] + [float(torque[i]) for i in range(3)]
        return reply

    def glide(self, request: dict[str, Any]) -> dict[str, Any]:
        """Move the tool from where it is to ``pos`` / ``quat`` at constant velocities over
        ``steps`` DEM steps, reading nothing (simulation steps the caller had no wrench for)."""
        tool, reader = self.tool, self.reader
        if tool is None or reader is None:
            msg = "no bed: send 'bed' first"
            raise RuntimeError(msg)
        steps = int(request["steps"])
        span = steps * O.dt
        here = Vector3(reader.origin)
        turn_here = O.bodies[tool.ids[0]].state.ori
        heading_here = turn_here * tool.q0
        axis, angle = (Quaternion(*request["quat"]) * heading_here.conjugate()).toAxisAngle()
        if angle > math.pi:
            angle -= 2 * math.pi
        v = (Vector3(*request["pos"]) - here) / span
        tool.snap(here, heading_here, v, axis * (angle / span))
        reader.start(here, v, False)
        O.run(steps, True)
        return self.progress()

    def progress(self) -> dict[str, Any]:
        """The DEM's time and its fastest sphere's speed (m/s). (A scan in Python, ~1 % of an
        exchange: the integrator's ``maxVelocitySq`` is reset only when the collider runs.)"""
        fastest = max(
            (b.state.vel.norm() for b in O.bodies if isinstance(b.shape, Sphere)), default=0.0
        )
        return {"ok": True, "time": O.time, "max_speed": fastest}

    def finish(self) -> dict[str, Any]:
        """The sample: the spheres in the tool's bounding box."""
        tool = self.tool
        if tool is None:
            msg = "no bed: send 'bed' first"
            raise RuntimeError(msg)
        count, volume = 0, 0.0
        for body in O.bodies:
            if isinstance(body.shape, Sphere) and tool.contains(body.state.pos):
                count += 1
                volume += 4.0 / 3.0 * math.pi * body.shape.radius**3
        particles = sum(1 for b in O.bodies if isinstance(b.shape, Sphere))
        assert self.grid is not None  # made with the template, before any bed
        change = bed_surface.height_change(self.heights_made, self.bulk_heights(tool))
        return {
            "ok": True,
            "surface": {**self.grid.to_dict(), "change": change},
            "sample_particles": count,
            "sample_volume_m3": volume,
            "sample_mass_kg": volume * self.density,
            "particles": particles,
            "time": O.time,
        }

    def bulk_heights(self, tool: LiveTool | None) -> list[list[float]]:
        """The bed's bulk heights (:func:`bed_surface.bulk_heights`), without the spheres in
        ``tool``'s bounding box."""
        assert self.grid is not None
        spheres = (
            (b.state.pos[0], b.state.pos[1], b.shape.radius)
            for b in O.bodies
            if isinstance(b.shape, Sphere) and (tool is None or not tool.contains(b.state.pos))
        )
        return bed_surface.bulk_heights(self.grid, spheres, self.solid_fraction)


def solid_fraction(job: dict[str, Any]) -> float:
    """The loaded template's solid fraction (1 - porosity): the volume of the spheres whose
    centres lie in the bed's box shrunk by a mean diameter from its walls, floor and top (away
    from the looser packing along them), over that box's volume."""
    margin = 2.0 * job["particle_radius"]
    bed = job["bed"]
    lo = (margin, -bed["width"] / 2 + margin, margin)
    hi = (bed["length"] - margin, bed["width"] / 2 - margin, bed["depth"] - margin)
    if not all(h > lo_i for lo_i, h in zip(lo, hi, strict=True)):
        msg = f"the bed {bed} is less than two sphere diameters ({2 * margin} m) thick"
        raise ValueError(msg)
    box = math.prod(h - lo_i for lo_i, h in zip(lo, hi, strict=True))
    solid = sum(
        4.0 / 3.0 * math.pi * b.shape.radius**3
        for b in O.bodies
        if isinstance(b.shape, Sphere) and all(lo[i] <= b.state.pos[i] <= hi[i] for i in range(3))
    )
    return solid / box


def bilinear(us: list[float], vs: list[float], h: list[list[float]], u: float, v: float) -> float:
    """Bilinear interpolation on a regular grid (held at its edges)."""

    def locate(axis: list[float], x: float) -> tuple[int, float]:
        step = (axis[-1] - axis[0]) / (len(axis) - 1)
        t = min(max((x - axis[0]) / step, 0.0), len(axis) - 1.0)
        i = min(int(t), len(axis) - 2)
        return i, t - i

    i, a = locate(us, u)
    j, b = locate(vs, v)
    return (
        (1 - a) * (1 - b) * h[j][i]
        + a * (1 - b) * h[j][i + 1]
        + (1 - a) * b * h[j + 1][i]
        + a * b * h[j + 1][i + 1]
    )


def serve(requests: Any, replies: Any) -> int:
    """Answer requests until end of file or ``quit``."""
    worker = Worker()
    replies.write((json.dumps({"ok": True, "op": "hello", "pid": os.getpid()}) + "\n").encode())
    replies.flush()
    for line in requests:
        request = json.loads(line)
        if request.get("op") == "quit":
            break
        try:
            reply = worker.handle(request)
        except Exception as error:  # reported to the caller, which raises DemRunError
            traceback.print_exc()
            reply = {"ok": False, "error": f"{type(error).__name__}: {error}"}
        replies.write((json.dumps(reply) + "\n").encode())
        replies.flush()
    return 0


def main(argv: list[str]) -> int:
    """``yade_live.py <request fd> <reply fd>``."""
    with os.fdopen(int(argv[1]), "rb") as requests, os.fdopen(int(argv[2]), "wb") as replies:
        return serve(requests, replies)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
