"""``rospy.init_node`` and ``rospy.spin`` for every node of the stack, with a node that stops in
~0.1 s, not ~0.6 s, and returns from its spin as soon as it has.

rospy's registration thread (``RegManager.run``) waits on a condition for up to 0.5 s at a time.
Its pre-shutdown cleanup wakes it before rospy raises its shutdown flag, so the thread goes back
to waiting, and ``rospy.signal_shutdown`` then joins it: every node took about 0.6 s to stop,
however little it did (a mission stops its stack in two waves; the tests stop one per module).
:func:`init_node` wakes the thread again once the flag is up, so it sees the flag and ends.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any, NoReturn, TypeVar

import rospy
import rospy.core
from rospy.impl import tcpros_base
from rospy.impl.registration import RegManager, get_registration_listeners

#: Connections rospy's TCPROS server lets wait to be accepted (rospy: 5).
TCPROS_BACKLOG = 128


#: s of wall time :func:`signal_shutdown` waits for rospy's shutdown hooks.
HOOKS_TIMEOUT_S = 5.0

_Result = TypeVar("_Result")


def quiet_at_shutdown(callback: Callable[..., _Result]) -> Callable[..., _Result | None]:
    """Wrap a callback that publishes (a subscriber's, a timer's): a publish that meets rospy
    shutting down is dropped, not raised. rospy closes a node's publishers in a pre-shutdown
    hook, before it raises its shutdown flag, and its own check of that flag lets a publish
    in between raise ``publish() to a closed topic``: its receive threads still deliver
    messages then, and it logged each such callback's traceback as a bad callback (a node
    stopping on an error, the battery that cannot start, buried its reason under them). Any
    other ``ROSException``, and any while no shutdown is under way, is raised as before."""

    @functools.wraps(callback)
    def wrapped(*args: Any, **kwargs: Any) -> _Result | None:
        try:
            return callback(*args, **kwargs)
        except rospy.ROSException:
            if rospy.core.is_shutdown_requested():  # set before the flag, never cleared
                return None
            raise

    return wrapped


def init_node(name: str, **kwargs: Any) -> None:
    """``rospy.init_node(name, **kwargs)``, then :func:`stop_promptly` and
    :func:`accept_many`; unless ``disable_signals``, SIGINT and SIGTERM shut the node down
    through :func:`signal_shutdown`'s thread (rospy's handler sleeps 0.1 s in the main thread
    after the hooks, and raises KeyboardInterrupt there)."""
    rospy.init_node(name, **kwargs)
    stop_promptly()
    accept_many()
    if not kwargs.get("disable_signals", False):
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, _on_signal)


def _on_signal(signum: int, _frame: Any) -> None:
    _shut_down_in_background(f"signal-{signum}")


def _shut_down_in_background(reason: str) -> threading.Event:
    """Run ``rospy.signal_shutdown(reason)`` on a thread of its own; the event is set once its
    shutdown hooks have run (the node has left the master and closed its connections)."""
    hooks_done = threading.Event()
    rospy.core.add_shutdown_hook(lambda _reason: hooks_done.set())  # after the others
    threading.Thread(
        target=rospy.core.signal_shutdown, args=(reason,), name="shutdown", daemon=True
    ).start()
    return hooks_done


def signal_shutdown(reason: str) -> None:
    """``rospy.signal_shutdown(reason)``, returning once its hooks have run: rospy then joins
    its threads and sleeps 0.1 s ("a hack until we get rid of all the extra threads"), which
    each node of a mission's stack paid in turn at its stop, and the mission once more."""
    if not rospy.core.is_initialized() or rospy.core.is_shutdown():
        return
    _shut_down_in_background(reason).wait(HOOKS_TIMEOUT_S)


def accept_many() -> None:
    """After ``rospy.init_node``: let the node's TCPROS server keep :data:`TCPROS_BACKLOG`
    connections waiting, not 5. rospy's server accepts one connection at a time (it reads the
    subscriber's header before it accepts the next), so when more than 5 subscribers connect at
    once (a recorder subscribing to 30 topics of a node) the kernel drops the others' SYNs and
    they retry 1 s later: the mission's stack took a second more to connect than it needed.
    Linux takes a new backlog from ``listen`` on a socket already listening."""
    server = tcpros_base.init_tcpros_server()  # the node's own, made by init_node
    server.start_server()
    if server.tcp_ros_server is not None:
        server.tcp_ros_server.server_sock.listen(TCPROS_BACKLOG)


def stop_promptly() -> None:
    """After ``rospy.init_node``: wake rospy's registration thread when the node shuts down,
    once rospy's shutdown flag is up (a shutdown hook runs after it is raised and before the
    threads are joined)."""
    # The cleanup empties the listeners before the shutdown hooks run: keep the managers now.
    managers = [m for m in get_registration_listeners().listeners if isinstance(m, RegManager)]

    def wake(reason: str) -> None:
        for manager in managers:
            with manager.cond:
                # An empty update: a thread not yet waiting does not wait (it checks the updates
                # under this lock), one waiting is woken; either way it then sees the flag.
                manager.updates.append((None, None))
                manager.cond.notify_all()

    rospy.core.add_shutdown_hook(wake)


def spin() -> None:
    """``rospy.spin()``, returning as soon as the node has shut down: rospy's looks at the
    shutdown flag every 0.5 s of wall time, which a node stopped by a signal then waited out in
    its main thread (0.25 s on average, each time a mission stops its stack)."""
    stopped = threading.Event()
    # Run at the shutdown (in the signal handler, for a signal), or at once if it is over.
    rospy.core.add_shutdown_hook(lambda _reason: stopped.set())
    try:
        while not stopped.wait(timeout=0.5) and not rospy.core.is_shutdown():
            pass
    except KeyboardInterrupt:  # what rospy.spin does, should the signal reach here
        rospy.core.signal_shutdown("keyboard interrupt")


def exit_now(code: int | None = 0) -> NoReturn:
    """End a node's process once its ``main`` has returned (rospy shut down), without Python's
    teardown of the modules it imported: the monitors' (ProgPy, pandas, scipy, matplotlib) took
    0.37 s to tear down, the longest part of stopping a mission's stack. The logs and the
    standard streams are flushed first. The node scripts call it with what ``main`` returned,
    so only after it has returned: the recorder's bag is closed by then, and no node leaves
    anything else to do at exit. A ``main`` that raises exits as Python does.

    A ``main`` that returns without rospy having shut down (a node refusing its parameters)
    is shut down here first, as rospy's own exit handler would: the node unregisters from the
    master. Left registered, the master went on calling its address, and once another node's
    TCPROS server took that port, the master's XML-RPC request stalled that server's accept
    loop for good (a test's service call hung).

    Args:
        code: the exit status (None: 0, as ``sys.exit``).
    """
    signal_shutdown("exit")
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # closed or gone: nothing to write
            stream.flush()
    os._exit(0 if code is None else code)
