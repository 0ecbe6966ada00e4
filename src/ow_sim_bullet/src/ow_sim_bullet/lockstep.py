"""Lockstep: the simulation waits for the clients that registered as synchronous, so what they
decide on a joint state takes effect at a simulation time that does not depend on how fast they
(or the machine) run. No ROS, no threads: :class:`~ow_sim_bullet.runner.SimRunner` guards it.

The protocol (docs/determinism.md): a client registers (its acknowledged stamp is then the sim
time of registration) and acknowledges every joint state it has processed. The simulation steps
from time ``t`` only once every client has acknowledged a joint state of ``t - latency`` or later
(and no client holds it at ``t``). What a client decides on the joint state of stamp ``s``
(set-points, a hold) rides on that acknowledgement and is applied at exactly ``s + latency``: the
simulation cannot have passed that time before the acknowledgement arrived. The latency is at
least the period of the slowest stream a client decides on, so the stream's next message after
``s`` is always published without waiting for the client.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

from ow_runtime.names import STAMP_SLACK_S

#: s of sim time: stamps this close count as equal (float and nanosecond rounding of stamps).
EPSILON = STAMP_SLACK_S


@dataclass
class ClientState:
    """A registered client.

    Attributes:
        order: registration order (ties between clients' commands are applied in it).
        acked: s (sim), the newest joint state it has processed.
        hold_until: s (sim), the time it holds the simulation at, or None.
        last_ack_wall: s (monotonic wall clock) of its last acknowledgement or registration.
        node: the node (ROS caller id) that registered it, whose subscriptions it decides on;
            None: not known (registered for it, e.g. expected from the start).
    """

    order: int
    acked: float
    hold_until: float | None
    last_ack_wall: float
    node: str | None = None

    def holds(self, now: float) -> bool:
        """Whether it holds the simulation at sim time ``now`` (s)."""
        return self.hold_until is not None and now >= self.hold_until - EPSILON


@dataclass(order=True)
class _Command:
    apply_at: float
    order: int
    seq: int
    joint: str = field(compare=False)
    position: float = field(compare=False)


class Lockstep:
    """The clients the simulation waits for, and the commands they decided.

    Args:
        latency_s: s of sim time from a joint state to the commands decided on it (> 0).
    """

    def __init__(self, latency_s: float) -> None:
        if not latency_s > 0 or not math.isfinite(latency_s):
            msg = f"lockstep latency {latency_s!r} s must be > 0"
            raise ValueError(msg)
        self.latency_s = latency_s
        self.clients: dict[str, ClientState] = {}
        self._commands: list[_Command] = []
        self._orders = 0
        self._seq = 0

    def register(
        self, name: str, now: float, hold: bool, wall: float = 0.0, node: str | None = None
    ) -> None:
        """Register ``name`` (again: afresh) at sim time ``now`` (s): it has seen everything up to
        then; ``hold``: the simulation steps no further than ``now`` until it releases it;
        ``node``: the node it runs in (see :meth:`awaited_nodes`)."""
        if not name:
            msg = "a lockstep client needs a name"
            raise ValueError(msg)
        self._orders += 1
        self.clients[name] = ClientState(self._orders, now, now if hold else None, wall, node)

    def unregister(self, name: str) -> bool:
        """Forget ``name`` (its commands not yet applied stay); False if it was not registered."""
        return self.clients.pop(name, None) is not None

    def ack(
        self,
        name: str,
        stamp: float,
        hold_until: float | None = None,
        commands: list[tuple[str, float]] | None = None,
        wall: float = 0.0,
    ) -> str | None:
        """``name`` has processed the joint states up to ``stamp`` (s, sim), holds the
        simulation at ``hold_until`` (s, sim; None: not) and decided ``commands`` (joint,
        set-point rad) on them, applied at ``stamp + latency``.

        Returns:
            None, or why the acknowledgement was ignored (the client is not registered) or what
            was wrong with it (a stamp older than the client's newest: its commands are
            applied with the newest's).
        """
        client = self.clients.get(name)
        if client is None:
            return f"lockstep acknowledgement of unregistered client {name!r} ignored"
        problem = None
        if stamp < client.acked - EPSILON:
            problem = (
                f"lockstep client {name!r} acknowledged t={stamp:.6f} s after t={client.acked:.6f}"
                " s: acknowledgements must not go back in time"
            )
            stamp = client.acked
        client.acked = stamp
        client.hold_until = hold_until
        client.last_ack_wall = wall
        for joint, position in commands or ():
            self._seq += 1
            heapq.heappush(
                self._commands,
                _Command(stamp + self.latency_s, client.order, self._seq, joint, position),
            )
        return problem

    def blocking(self, now: float) -> tuple[str, str] | None:
        """Why the simulation may not step from sim time ``now`` (s): (client, "hold") when a
        client holds it there, (client, "ack") when a client has not yet acknowledged the joint
        state of ``now - latency``; None when it may step. Holds are reported first."""
        waiting = None
        for name, client in self.clients.items():
            if client.holds(now):
                return name, "hold"
            if waiting is None and now > client.acked + self.latency_s + EPSILON:
                waiting = (name, "ack")
        return waiting

    def awaited_nodes(self, now: float) -> frozenset[str] | None:
        """The nodes of the clients whose acknowledgement the step from sim time ``now`` (s)
        waits for: what they decide on must reach them now, everything else can wait. None
        when one of them has no known node (write to everyone)."""
        nodes = set()
        for client in self.clients.values():
            if now > client.acked + self.latency_s + EPSILON:
                if client.node is None:
                    return None
                nodes.add(client.node)
        return frozenset(nodes)

    def holding(self, now: float) -> list[str]:
        """The clients that hold the simulation at sim time ``now`` (s), in registration order."""
        return [name for name, client in self.clients.items() if client.holds(now)]

    def due(self, now: float) -> list[tuple[str, float]]:
        """The commands (joint, set-point rad) to apply before the step from ``now`` (s, sim),
        in order: by the time they were decided for, then client registration, then arrival."""
        commands = []
        while self._commands and self._commands[0].apply_at <= now + EPSILON:
            command = heapq.heappop(self._commands)
            commands.append((command.joint, command.position))
        return commands

    def silent(self, now: float, wall: float, timeout_s: float) -> list[str]:
        """Clients the step from ``now`` (s, sim) waits for with no acknowledgement for more
        than ``timeout_s`` of wall time (``wall``: the monotonic clock now). A hold is not
        waiting: a client may hold the simulation as long as it likes."""
        return [
            name
            for name, client in self.clients.items()
            if client.hold_until is None
            and now > client.acked + self.latency_s + EPSILON
            and wall - client.last_ack_wall > timeout_s
        ]
