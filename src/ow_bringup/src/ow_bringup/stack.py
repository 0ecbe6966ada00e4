"""Run a private ROS master and real nodes from Python: used by the mission and the test harness.

:func:`private_master` starts ``rosmaster --core`` on a free port of 127.0.0.1; a
:class:`RosStack` starts nodes on it as ``rosrun`` would (:func:`node_command`), waits for their
services or topics, and stops them (SIGINT, and SIGTERM for a process that ignores it, then
SIGKILL of each node's whole process group). Each node's output goes to
``<log_dir>/<name>.log`` (``<name>.1.log`` ... for a name started again); a node that dies
or never becomes ready raises :class:`HarnessError` with the end of that log.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import socket
import subprocess
import tempfile
import threading
import time
import urllib.parse
import xmlrpc.client
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ow_bringup.errors import HarnessError
from ow_bringup.processes import (
    end_process_group,
    interrupt_process_group,
    log_tail,
    new_log_path,
    stop_process_group,
)

_HARNESS_CALLER = "/ow_testing_harness"


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


#: ``PYTHONOPTIMIZE`` of the nodes a stack starts: 2 is ``python -OO``, without docstrings
#: (and ``assert`` statements: the nodes' code uses them only to narrow types). A node's
#: docstrings are never read while it runs, and they took ~20 MB of the mission's stack
#: (docs/history/performance-journal.md, tenth round).
NODE_PYTHON_OPTIMIZE = "2"
#: What a stack adds to its nodes' environment: :data:`NODE_PYTHON_OPTIMIZE`; one thread for
#: OpenBLAS (numpy's and scipy's): the nodes' matrices are a few rows, and a pool of BLAS threads
#: per process did nothing for them but start, ~0.14 CPU-s per process importing numpy; and
#: one glibc malloc arena: rospy's threads (one per connection) each took an arena of their
#: own, and the stack's peak PSS during a mission was 474-476 MB with one against 494-500 MB
#: (docs/history/performance-journal.md, eleventh round). The nodes' threads take turns at the
#: GIL anyway. A user's own setting wins.
NODE_ENVIRONMENT = {
    "PYTHONOPTIMIZE": NODE_PYTHON_OPTIMIZE,
    "OPENBLAS_NUM_THREADS": "1",
    "MALLOC_ARENA_MAX": "1",
}


@functools.cache
def node_command(package: str, executable: str) -> tuple[str, ...]:
    """The command that runs ``executable`` of ``package``: the program catkin made for it in
    the workspace (``devel/lib/<package>/`` or the install space's), the first ``rosrun``
    finds; ``rosrun <package> <executable>`` itself when there is none (a script kept in the
    package's sources). The same program as rosrun's, without the shell, the three
    ``catkin_find`` runs and the ``rospack`` that rosrun spends ~0.3 s of CPU on per node."""
    from catkin.find_in_workspaces import find_in_workspaces  # ROS's, not on every path

    for path in find_in_workspaces(["libexec"], project=package, path=executable):
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return (path,)
    return ("rosrun", package, executable)


def _namespaces(name: str) -> list[str]:
    """The namespaces enclosing parameter ``name``, outermost first (``/a/b/c``: ``/a``,
    ``/a/b``)."""
    parts = name.split("/")
    return ["/".join(parts[:k]) for k in range(2, len(parts))]


def new_param_roots(kept: Iterable[str], names: Iterable[str]) -> list[str]:
    """What to delete so that of parameters ``names`` only ``kept`` remain: for each name not
    kept, its outermost namespace that encloses no kept name (a new ``/faults`` goes whole,
    without the empty namespace deleting its parameters one by one would leave), else the name.

    Args:
        kept: full parameter names to keep (``/use_sim_time``), as ``getParamNames`` lists them.
        names: full parameter names on the master now.

    Returns:
        Sorted full names of parameters and namespaces, none inside another.
    """
    kept = set(kept)
    occupied = {ns for name in kept for ns in _namespaces(name)}
    return sorted(
        {
            next((ns for ns in _namespaces(name) if ns not in occupied), name)
            for name in set(names) - kept
        }
    )


#: Master methods an in-process master answers without XML-RPC: read-only, and answered with
#: lists made for the call (rosmaster's ``Registrations.get_state``), never its own state.
_DIRECT_METHODS = frozenset({"getSystemState"})


@dataclass
class RosMaster:
    """A private ``rosmaster --core`` on a free port of 127.0.0.1.

    Attributes:
        log_dir: directory for ROS_HOME, the master's and every node's logs.
        port: TCP port of the master (chosen free when 0).
        in_process: run the master (rosmaster's own ``Master``: the same XML-RPC API and
            parameter server) on threads of this process instead of a process of its own:
            ~40 MB of PSS less, for a process that must outlive every node anyway (the
            mission's). Its log goes to this process's ``rosmaster`` logger.
    """

    log_dir: Path
    port: int = 0
    in_process: bool = False
    proc: subprocess.Popen[bytes] | None = field(default=None, init=False)
    _master: Any = field(default=None, init=False, repr=False)

    @property
    def uri(self) -> str:
        """The master's XML-RPC URI."""
        return f"http://127.0.0.1:{self.port}"

    @property
    def env(self) -> dict[str, str]:
        """Environment for processes that should talk to this master."""
        env = dict(os.environ)
        env.update(
            ROS_MASTER_URI=self.uri,
            ROS_HOSTNAME="127.0.0.1",
            ROS_HOME=str(self.log_dir),
            ROS_LOG_DIR=str(self.log_dir / "log"),
            PYTHONUNBUFFERED="1",
        )
        env.pop("ROS_IP", None)
        return env

    def start(self, timeout_s: float = 20.0) -> None:
        """Start the master and wait until it answers."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        if not self.port:
            self.port = free_port()
        if self.in_process:
            self._start_in_process(timeout_s)
            return
        log = (self.log_dir / "rosmaster.log").open("wb")
        self.proc = subprocess.Popen(
            ["rosmaster", "--core", "-p", str(self.port)],
            env=self.env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                tail = log_tail(self.log_dir / "rosmaster.log")
                msg = f"rosmaster on port {self.port} exited: {tail}"
                raise HarnessError(msg)
            with contextlib.suppress(OSError):
                self.call("getSystemState")
                return
            time.sleep(0.05)
        self.stop()
        msg = f"rosmaster on port {self.port} did not answer within {timeout_s} s"
        raise HarnessError(msg)

    def _start_in_process(self, timeout_s: float) -> None:
        """rosmaster's ``Master.start``, with its server thread's failure (a port taken since
        it was chosen) raised here: ``Master.start`` would wait for it forever."""
        from rosgraph.xmlrpc import XmlRpcNode
        from rosmaster.master_api import NUM_WORKERS, ROSMasterHandler

        errors: list[Exception] = []
        node = XmlRpcNode(self.port, ROSMasterHandler(NUM_WORKERS), on_run_error=errors.append)
        node.start()
        deadline = time.monotonic() + timeout_s
        while not node.uri:
            if errors or time.monotonic() > deadline:
                node.shutdown("the harness gave up on it")
                reason = errors[0] if errors else f"no answer within {timeout_s} s"
                msg = f"rosmaster on port {self.port} could not start: {reason}"
                raise HarnessError(msg)
            time.sleep(0.001)
        self._master = node
        self.call("getSystemState")

    def stop(self) -> None:
        """Stop the master."""
        if self.proc is not None:
            stop_process_group(self.proc)
            self.proc = None
        if self._master is not None:
            self._master.shutdown("stopped by the harness")
            self._master = None

    def call(self, method: str, *args: Any, caller: str = _HARNESS_CALLER) -> Any:
        """Call a master or parameter-server XML-RPC method as ``caller``; return its value,
        raise on failure.

        An in-process master answers :data:`_DIRECT_METHODS` by a plain call of its handler:
        the same value without the XML both ways, on the threads of one process (the mission
        polls ``getSystemState`` while its nodes start: ~0.2 CPU-s of XML a mission)."""
        if self._master is not None and method in _DIRECT_METHODS:
            code, status, value = getattr(self._master.handler, method)(caller, *args)
        else:
            proxy = xmlrpc.client.ServerProxy(self.uri)
            code, status, value = getattr(proxy, method)(caller, *args)
        if code != 1:
            msg = f"master call {method}{args} failed: {status}"
            raise HarnessError(msg)
        return value

    def set_param(self, key: str, value: Any) -> None:
        """Set a parameter on the master (dicts become namespaces)."""
        self.call("setParam", key, value)

    def delete_param(self, key: str) -> None:
        """Delete a parameter if it exists."""
        with contextlib.suppress(HarnessError):
            self.call("deleteParam", key)

    def param_snapshot(self) -> dict[str, Any]:
        """Every parameter on the master now: full name -> value."""
        return {name: self.call("getParam", name) for name in self.call("getParamNames")}

    def restore_params(self, snapshot: Mapping[str, Any]) -> None:
        """Put the parameters back as :meth:`param_snapshot` found them: every parameter set
        since is deleted (a new namespace whole, :func:`new_param_roots`), and one changed or
        deleted since is set back."""
        for root in new_param_roots(snapshot, self.call("getParamNames")):
            self.delete_param(root)
        for name, value in snapshot.items():
            if not self.call("hasParam", name) or self.call("getParam", name) != value:
                self.set_param(name, value)

    def services(self) -> set[str]:
        """Names of all services registered right now."""
        _, _, services = self.call("getSystemState")
        return {name for name, _ in services}

    def published_topics(self) -> set[str]:
        """Names of all topics that have a publisher right now."""
        publishers, _, _ = self.call("getSystemState")
        return {name for name, _ in publishers}

    def unconnected(self, topics: Iterable[str] | None = None) -> list[str]:
        """Topics (of ``topics``; None: all) with a subscriber the master lists that one of
        their publishers is not yet sending to: a publisher adds a connection on its side last,
        and what it publishes before then does not reach that subscriber."""
        publishers: list[tuple[str, list[str]]]
        subscribers: list[tuple[str, list[str]]]
        publishers, subscribers, _ = self.call("getSystemState")
        wanted = None if topics is None else set(topics)
        listening = {name: len(nodes) for name, nodes in subscribers}
        sending: dict[str, dict[str, int]] = {}  # publisher node -> topic -> connections
        missing = []
        for name, nodes in publishers:
            if (wanted is not None and name not in wanted) or not listening.get(name):
                continue
            for node in nodes:
                if node not in sending:
                    sending[node] = _outbound_connections(str(self.call("lookupNode", node)))
                if sending[node].get(name, 0) < listening[name]:
                    missing.append(name)
                    break
        return missing

    def forget(self, node: str) -> list[str]:
        """Unregister whatever node ``node`` (e.g. ``/sim``; its process gone) left on the
        master, as ``rosnode cleanup`` does; the names unregistered. A node killed before it
        could unregister stays listed as a subscriber, and every later wait for the topic's
        publishers to connect to all of its subscribers (:meth:`unconnected`) ran out: a
        later module's stack waited out its whole deadline (30-60 s) before its first step."""
        publishers, subscribers, services = self.call("getSystemState")
        try:
            api = str(self.call("lookupNode", node))
        except HarnessError:
            return []  # not registered (any more)
        gone = []
        for method, entries in (
            ("unregisterPublisher", publishers),
            ("unregisterSubscriber", subscribers),
        ):
            for topic, nodes in entries:
                if node in nodes:
                    self.call(method, topic, api, caller=node)
                    gone.append(topic)
        for service, providers in services:
            if node in providers:
                with contextlib.suppress(HarnessError):  # gone meanwhile
                    uri = str(self.call("lookupService", service))
                    self.call("unregisterService", service, uri, caller=node)
                    gone.append(service)
        return gone

    def forget_unreachable(self) -> list[str]:
        """:meth:`forget` every node registered on the master whose XML-RPC
        server refuses connections: its process is gone. A test that killed a node it started
        by itself (a raw ``rospy`` script) left it a subscriber of ``/clock``; a module's
        stack does this when it ends, so the next module's waits are not on the dead."""
        publishers, subscribers, services = self.call("getSystemState")
        names = {n for _, nodes in (*publishers, *subscribers, *services) for n in nodes}
        forgotten = []
        for name in sorted(names):
            try:
                api = urllib.parse.urlsplit(str(self.call("lookupNode", name)))
            except HarnessError:
                continue
            try:
                with socket.create_connection((api.hostname, api.port), timeout=1.0):
                    continue  # it answers: alive
            except ConnectionRefusedError:
                pass
            except OSError:
                continue  # slow or unreachable for another reason: not known to be dead
            if self.forget(name):
                forgotten.append(name)
        return forgotten

    def publishers(self, topic: str) -> list[str]:
        """The nodes that have registered a publisher of ``topic``."""
        publishers, _, _ = self.call("getSystemState")
        return next((list(nodes) for name, nodes in publishers if name == topic), [])

    def subscribed_by(self, node: str) -> set[str]:
        """The topics node ``node`` (e.g. ``/arm_services``) has registered a subscriber of."""
        _, subscribers, _ = self.call("getSystemState")
        return {name for name, nodes in subscribers if node in nodes}

    def offered_by(self, node: str) -> tuple[set[str], set[str]]:
        """(services, published topics) that node ``node`` (e.g. ``/sim``) has registered."""
        publishers, _, services = self.call("getSystemState")
        return (
            {name for name, providers in services if node in providers},
            {name for name, nodes in publishers if node in nodes},
        )


def wait_until(condition: Callable[[], bool], timeout_s: float, poll_s: float = 0.05) -> bool:
    """Wait until ``condition()`` holds (``timeout_s`` of wall time at most); whether it did."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(poll_s)
    return True


def _outbound_connections(node_uri: str) -> dict[str, int]:
    """Topic -> open outbound connections of the node at ``node_uri`` (its ``getBusInfo``);
    empty when it does not answer (it is stopping)."""
    try:
        reply: Any = xmlrpc.client.ServerProxy(node_uri).getBusInfo(_HARNESS_CALLER)
    except (OSError, xmlrpc.client.Error):
        return {}
    counts: dict[str, int] = {}
    for connection in reply[2]:  # [id, destination, direction, transport, topic, connected, ..]
        if connection[2] == "o" and connection[5]:
            counts[connection[4]] = counts.get(connection[4], 0) + 1
    return counts


@dataclass
class NodeProcess:
    """A node started by :meth:`RosStack.start_node`."""

    name: str
    proc: subprocess.Popen[bytes]
    log_path: Path

    def alive(self) -> bool:
        """True while the node's process runs."""
        return self.proc.poll() is None

    def log(self) -> str:
        """Everything the node printed so far."""
        return self.log_path.read_text(errors="replace")

    def stop(self, timeout_s: float = 10.0) -> int | None:
        """Stop the node (SIGINT, SIGTERM if it ignores that, then SIGKILL of its process group);
        return its exit code."""
        stop_process_group(self.proc, timeout_s)
        return self.proc.returncode

    def signal(self, sig: int) -> None:
        """Send a signal to the node's whole process group."""
        os.killpg(self.proc.pid, sig)


@dataclass
class RosStack:
    """Real nodes on a private master; stops them all in :meth:`shutdown`."""

    master: RosMaster
    nodes: list[NodeProcess] = field(default_factory=list)
    params: list[str] = field(default_factory=list)

    def start_node(
        self,
        package: str,
        executable: str,
        name: str | None = None,
        args: Iterable[str] = (),
        params: Mapping[str, Any] | None = None,
        wait_for_services: Iterable[str] = (),
        wait_for_topics: Iterable[str] = (),
        timeout_s: float = 60.0,
        wait: bool = True,
    ) -> NodeProcess:
        """Start ``rosrun <package> <executable>`` (:func:`node_command`) and wait until it is
        ready.

        Args:
            package: ROS package, e.g. ``ow_sim_bullet``.
            executable: node executable in the package, e.g. ``sim``.
            name: node name (default: the executable's name); private parameters go to ``/<name>/``.
            args: extra command-line arguments (e.g. remappings ``"a:=b"``).
            params: private parameters, set on the master before the node starts.
            wait_for_services: service names the node must offer before this returns.
            wait_for_topics: topic names the node must publish before this returns.
            timeout_s: s of wall time to wait for them.
            wait: False returns at once (start several nodes side by side, then
                :meth:`wait_ready` for each).

        Returns:
            The running node.

        Raises:
            HarnessError: the node exited or was not ready in time (with the end of its log).
        """
        node_name = name or executable
        for key, value in (params or {}).items():
            full = f"/{node_name}/{key}"
            self.master.set_param(full, value)
            self.params.append(full)
        log_path = new_log_path(self.master.log_dir, node_name)
        log = log_path.open("wb")
        proc = subprocess.Popen(
            [*node_command(package, executable), f"__name:={node_name}", *args],
            env={**NODE_ENVIRONMENT, **self.master.env, "PYTHONOPTIMIZE": NODE_PYTHON_OPTIMIZE},
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        node = NodeProcess(node_name, proc, log_path)
        self.nodes.append(node)
        if wait:
            self.wait_ready(node, wait_for_services, wait_for_topics, timeout_s)
        return node

    def wait_ready(
        self,
        node: NodeProcess,
        services: Iterable[str] = (),
        topics: Iterable[str] = (),
        timeout_s: float = 60.0,
    ) -> None:
        """Wait until ``node`` offers ``services`` and publishes ``topics``.

        Raises:
            HarnessError: the node exited or was not ready in time (with the end of its log).
        """
        self._wait(node, set(services), set(topics), timeout_s)

    def _wait(
        self, node: NodeProcess, services: set[str], topics: set[str], timeout_s: float
    ) -> None:
        deadline = time.monotonic() + timeout_s
        while True:
            if not node.alive():
                tail = log_tail(node.log_path)
                msg = f"node {node.name} exited with {node.proc.returncode}:\n{tail}"
                raise HarnessError(msg)
            # Offered by this node: a node of the same name stopping may still be registered.
            offered_services, offered_topics = self.master.offered_by(f"/{node.name}")
            missing = (services - offered_services) | (topics - offered_topics)
            if not missing:
                return
            if time.monotonic() > deadline:
                msg = (
                    f"node {node.name} did not offer {sorted(missing)} within {timeout_s} s:\n"
                    f"{log_tail(node.log_path)}"
                )
                raise HarnessError(msg)
            time.sleep(0.05)

    def wait_for_service(self, service: str, timeout_s: float = 30.0) -> None:
        """Wait until ``service`` is offered by any node."""
        deadline = time.monotonic() + timeout_s
        while service not in self.master.services():
            if time.monotonic() > deadline:
                msg = f"service {service} not offered within {timeout_s} s"
                raise HarnessError(msg)
            time.sleep(0.05)

    def service(self, name: str, service_class: Any, timeout_s: float = 30.0) -> Any:
        """A persistent-free ``rospy.ServiceProxy`` for ``name``, after waiting for the service."""
        from ow_runtime.connections import service_proxy

        self.wait_for_service(name, timeout_s)
        return service_proxy(name, service_class)

    def shutdown(self, last: Iterable[str] = (), delete_params: bool = True) -> None:
        """Stop every node started here and delete the parameters set for them.

        Args:
            last: names of nodes stopped only once all the others have exited, e.g. a recorder:
                it then has every message they sent (their connections close after them).
            delete_params: False for a master about to close (a mission's): deleting its ~50
                parameters one call each took 0.13 s. True also unregisters what a killed
                node left registered (:meth:`RosMaster.forget`).

        Each wave is interrupted at once, then waited for (10 s at most, then killed): a node
        takes about a second to shut rospy down, and one after the other that added up.
        """
        later = set(last)
        for wave in (
            [node for node in self.nodes if node.name not in later],
            [node for node in self.nodes if node.name in later],
        ):
            for node in reversed(wave):
                interrupt_process_group(node.proc)
            deadline = time.monotonic() + 10.0
            for node in reversed(wave):
                end_process_group(node.proc, max(0.0, deadline - time.monotonic()))
        # What a node killed (by a test, or after the wait above) left on a master that stays.
        for node in self.nodes if delete_params else ():
            self.master.forget(f"/{node.name}")
        self.nodes.clear()
        for key in self.params if delete_params else ():
            self.master.delete_param(key)
        self.params.clear()


@contextlib.contextmanager
def private_master(
    log_dir: Path | None = None, use_sim_time: bool = True, in_process: bool = False
) -> Iterator[RosMaster]:
    """Start a private master for the duration of a ``with`` block (outside pytest, e.g. scripts).

    Args:
        log_dir: where ROS_HOME and the logs go (default: a new temporary directory).
        use_sim_time: value of ``/use_sim_time`` on the new master.
        in_process: run it on threads of this process (:class:`RosMaster`).
    """
    directory = log_dir or Path(tempfile.mkdtemp(prefix="ow_ros_"))
    master = RosMaster(directory, in_process=in_process)
    with _exit_on_termination():
        master.start()
        try:
            master.set_param("/use_sim_time", use_sim_time)
            yield master
        finally:
            master.stop()


@contextlib.contextmanager
def _exit_on_termination() -> Iterator[None]:
    """While open, SIGTERM and SIGHUP raise SystemExit in the main thread instead of killing the
    process outright, so that the ``finally`` blocks stopping the nodes run: a killed mission or
    script must not leave its simulation running at full speed with no master."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def leave(signum: int, _frame: Any) -> None:
        raise SystemExit(128 + signum)

    previous = {sig: signal.signal(sig, leave) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def call_with_timeout(
    proxy: Callable[..., Any], fields: Mapping[str, Any], timeout_s: float
) -> Any:
    """``proxy(**fields)``, or TimeoutError after ``timeout_s`` s of wall time.

    A call that times out is left running in a daemon thread; the mission then stops and shuts
    the stack down, which ends it.

    Raises:
        TimeoutError: no answer within ``timeout_s``.
        Exception: whatever the call raised.
    """
    outcome: dict[str, Any] = {}

    def call() -> None:
        try:
            outcome["response"] = proxy(**fields)
        except Exception as exc:  # re-raised in the caller's thread
            outcome["error"] = exc

    worker = threading.Thread(target=call, name="mission-step", daemon=True)
    worker.start()
    worker.join(timeout_s)
    if worker.is_alive():
        raise TimeoutError
    if "error" in outcome:
        raise outcome["error"]
    return outcome["response"]
