"""Ray for the agent scripts: joining a cluster (``--address``, checked before anything starts)
and a local cluster of several nodes on loopback (the tests and the benchmark).

A job joins a cluster with :func:`connect`: ``None`` starts Ray on this machine (``ray.init()``,
listening on the loopback address 127.0.0.2),
``HOST:PORT`` joins the cluster whose head listens there (``ray start --head --port PORT``),
``auto`` the one started on this machine. The job ships the ``agents`` package to the cluster's
workers (a runtime environment's ``py_modules``); ``esp_gym`` and its ``[ray]`` extra must be
installed on every node. Numba and torch get one thread in the workers (each takes one CPU).

:class:`LocalCluster` starts a head and worker nodes as ``ray start --block`` processes with
their own temporary directories and ports, and stops every process it started, by its id
(``ray stop`` would stop every Ray process of the user, other clusters included).
"""
from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import Optional

from agents import PACKAGE

#: What a Ray worker of these jobs runs with: one numba and one torch thread per CPU it holds.
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class AddressError(ValueError):
    """An ``--address`` that is not ``HOST:PORT`` or ``auto``, or that no Ray head answers on."""


def check_address(address: Optional[str], timeout: float = 5.0) -> Optional[str]:
    """``address`` if it is None, ``auto`` or a ``HOST:PORT`` that accepts a connection within
    ``timeout`` seconds; else :class:`AddressError` (one line). ``ray.init`` itself would retry
    for a minute before failing."""
    if address is None or address == "auto":
        return address
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise AddressError(f"{address!r} is not HOST:PORT (the head's address, as `ray start --head` prints it) "
                           f"or 'auto'")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            pass
    except OSError as err:
        raise AddressError(f"no Ray head answers at {address} ({err.strerror or type(err).__name__}); start one with "
                           f"`ray start --head --port {port}` or give the address it prints") from None
    return address


def token_auth(address: Optional[str]) -> None:
    """Joining a cluster, ask for Ray's token authentication where ``ray start`` turns it on (when
    RAY_AUTH_MODE is unset and a token is at hand: RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or
    ~/.ray/auth_token); a driver leaves it off unless told. Takes effect only before ``import ray``."""
    if address is None or "RAY_AUTH_MODE" in os.environ or "ray" in sys.modules:
        return
    if (os.environ.get("RAY_AUTH_TOKEN") or os.environ.get("RAY_AUTH_TOKEN_PATH")
            or (Path.home() / ".ray" / "auth_token").is_file()):
        os.environ["RAY_AUTH_MODE"] = "token"


def connect(address: Optional[str]) -> None:
    """Start or join Ray (see the module docstring); ``address`` is checked first."""
    check_address(address)
    token_auth(address)
    import ray

    runtime_env = {"py_modules": [str(PACKAGE)], "env_vars": dict(WORKER_ENV)}
    # Ray on this machine listens on a loopback address (Ray would take the machine's network
    # address, and replaces 127.0.0.1 by it); a cluster's nodes have their own addresses
    local = {"_node_ip_address": node_ip(0)} if address is None else {}
    ray.init(address=address, runtime_env=runtime_env, include_dashboard=False, log_to_driver=False,
             configure_logging=True, logging_level="warning", **local)


def shutdown() -> None:
    """Leave Ray, if this process joined it."""
    if "ray" in sys.modules:
        sys.modules["ray"].shutdown()


def cluster_nodes() -> list:
    """The alive nodes: ``{"node_id", "address", "cpus"}`` each."""
    import ray

    return [{"node_id": n["NodeID"], "address": n["NodeManagerAddress"], "cpus": n["Resources"].get("CPU", 0.0)}
            for n in ray.nodes() if n["Alive"]]


def node_ip(index: int) -> str:
    """The loopback address of a local cluster's node ``index``: 127.0.0.2 for the head, .3, ...
    for the workers (Ray replaces 127.0.0.1 by the machine's network address; any other address
    of the loopback range it keeps, and each node gets its own, like machines of a network)."""
    return f"127.0.0.{index + 2}"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class LocalCluster:
    """A Ray cluster of ``nodes`` nodes on this machine (loopback), ``cpus`` CPUs each: the head
    and ``nodes - 1`` workers, each a ``ray start --block`` process in its own process group with
    its own short temporary directory (Unix socket paths are limited to 107 characters).

    ``with LocalCluster(2) as c: ... c.address ...``; :meth:`stop` (also on leaving the block,
    failures included) ends every process the nodes started, found by process id.

    A node whose ``ray start`` exits, or does not report its node running within ``timeout``
    seconds, is started again, up to ``attempts`` times in all, with new ports and a new
    directory: Ray gives a raylet a fixed 30 s to register with the head, which a loaded machine
    can miss; the processes of the failed attempt are ended first. The error after the last
    attempt quotes its log and its raylet's.
    """

    def __init__(self, nodes: int = 2, cpus: int = 1, timeout: float = 60.0, token: Optional[str] = None,
                 attempts: int = 3):
        if attempts < 1:
            raise ValueError(f"attempts={attempts!r}: a node needs at least one attempt to start")
        self.nodes, self.cpus, self.timeout, self.attempts = nodes, cpus, timeout, attempts
        self.port = free_port()
        self.address = f"{node_ip(0)}:{self.port}"
        self.root = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))
        self.procs: list = []
        self.logs: list = []  # each node's current ``ray start`` log
        #: what a driver of this cluster needs in its environment (before it imports ray): the
        #: cluster's token (Ray's token authentication, whether or not the user has a token of
        #: their own); ``token`` (default: a new one) lets one driver join several clusters
        self.env = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": token or uuid.uuid4().hex}

    def __enter__(self) -> "LocalCluster":
        try:
            self.start()
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def node_command(self, index: int, temp: Path) -> list:
        """The ``ray start`` command of node ``index``, with new ports and directory ``temp``."""
        node = (["--head", "--port", str(self.port), "--include-dashboard", "false"] if index == 0
                else ["--address", self.address])
        ports = ["--node-manager-port", free_port(), "--object-manager-port", free_port(),
                 "--metrics-export-port", free_port(), "--runtime-env-agent-port", free_port(),
                 "--dashboard-agent-listen-port", free_port(), "--dashboard-agent-grpc-port", free_port()]
        return [str(Path(sys.executable).with_name("ray")), "start", *node, "--node-ip-address", node_ip(index),
                "--num-cpus", str(self.cpus), "--temp-dir", str(temp), "--disable-usage-stats", "--block",
                *map(str, ports)]

    def _start_node(self, index: int, attempt: int) -> None:
        if index == 0 and attempt > 0:  # the failed head may still hold its port
            self.port = free_port()
            self.address = f"{node_ip(0)}:{self.port}"
        temp = self.root / (f"n{index}" if attempt == 0 else f"n{index}.{attempt}")
        temp.mkdir()
        log_path = temp.with_name(temp.name + ".log")
        env = {**os.environ, **WORKER_ENV, **self.env, "RAY_USAGE_STATS_ENABLED": "0"}
        with open(log_path, "w") as log:
            proc = subprocess.Popen(self.node_command(index, temp), stdout=log, stderr=subprocess.STDOUT, env=env,
                                    start_new_session=True, cwd=self.root)
        if index < len(self.procs):
            self.procs[index], self.logs[index] = proc, log_path
        else:
            self.procs.append(proc)
            self.logs.append(log_path)

    def start(self) -> None:
        for index in range(self.nodes):
            for attempt in range(self.attempts):
                self._start_node(index, attempt)
                outcome = self._wait(index)
                if outcome == "started":
                    break
                if attempt + 1 == self.attempts:
                    what = (f"exited ({self.procs[index].returncode})" if outcome == "exited"
                            else f"did not start within {self.timeout:.0f} s")
                    raise RuntimeError(f"ray start of node {index} {what} {self.attempts} times in all; the last "
                                       f"time:\n{self._failure(index)}")
                self._end_node(index)

    def _started(self, index: int) -> bool:
        """Whether ``ray start`` of node ``index`` says its node runs (its raylet registered)."""
        return "Ray runtime started" in self.logs[index].read_text()

    def _wait(self, index: int) -> str:
        """``started``, ``exited`` (its ``ray start`` ended first) or ``timeout`` (neither within
        ``timeout`` seconds), for node ``index``."""
        end = time.monotonic() + self.timeout
        while not self._started(index):
            if self.procs[index].poll() is not None:
                return "exited"
            if time.monotonic() > end:
                return "timeout"
            time.sleep(0.5)
        return "started"

    def _failure(self, index: int) -> str:
        """The tails of node ``index``'s ``ray start`` log and of its raylet's log."""
        text = f"{self.logs[index]}:\n{self.logs[index].read_text()[-2000:]}"
        temp = self.logs[index].with_suffix("")
        for raylet in sorted(temp.glob("session_*/logs/raylet.out"))[-1:]:
            text += f"\n{raylet}:\n{raylet.read_text(errors='replace')[-2000:]}"
        return text

    def _end_node(self, index: int) -> None:
        """End every process of node ``index``'s current attempt (see :meth:`stop`)."""
        import psutil

        temp = str(self.logs[index].with_suffix(""))
        procs = self._tree(self.procs[index]) + [
            p for p in psutil.process_iter(["cmdline"]) if temp in " ".join(p.info["cmdline"] or ())]
        _end(procs, grace=10.0)

    def processes(self) -> list:
        """Process ids of every process the nodes run: the ``ray start`` processes, their
        descendants, and any process whose command line names this cluster's directory."""
        import psutil

        found = {p.pid: p for proc in self.procs for p in self._tree(proc)}
        for p in psutil.process_iter(["cmdline"]):
            if str(self.root) in " ".join(p.info["cmdline"] or ()):
                found[p.pid] = p
        return [found[k] for k in sorted(found)]

    @staticmethod
    def _tree(proc) -> list:
        """The process ``proc`` (a Popen) and its descendants, as psutil processes."""
        import psutil

        try:
            top = psutil.Process(proc.pid)
            return [top] + top.children(recursive=True)
        except psutil.NoSuchProcess:
            return []

    def stop(self, grace: float = 10.0) -> None:
        """SIGTERM to each node's ``ray start`` process, which stops its node's processes in
        order, and up to ``grace`` seconds for them to end; then SIGTERM to every process of
        :meth:`processes` (as found before the first signal, so none is lost to an exited parent)
        still running, SIGKILL to those alive after another ``grace`` seconds; then the temporary
        directory goes. (Signalled all at once, a node's processes wait for each other: measured
        on two nodes, the raylets took 10 s and the GCS and ``ray start`` outlived 15 s; the
        ``ray start`` processes alone end both nodes within 2 s.)"""
        import psutil

        procs = self.processes()
        tops = [p for proc in self.procs for p in self._tree(proc)[:1]]
        for p in tops:
            _signal(p, signal.SIGTERM)
        psutil.wait_procs(tops, timeout=grace)
        _end(procs, grace, again=self.processes)
        for proc in self.procs:
            try:
                proc.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                pass
        shutil.rmtree(self.root, ignore_errors=True)


def _end(procs: list, grace: float, again=lambda: []) -> None:
    """SIGTERM to ``procs``; SIGKILL to those alive after ``grace`` seconds and to ``again()``
    (processes started meanwhile)."""
    import psutil

    for p in procs:
        _signal(p, signal.SIGTERM)
    _, alive = psutil.wait_procs(procs, timeout=grace)
    for p in alive + again():
        _signal(p, signal.SIGKILL)
    psutil.wait_procs(alive, timeout=grace)


def _signal(p, sig) -> None:
    try:
        p.send_signal(sig)
    except Exception:  # psutil.NoSuchProcess: already gone
        pass
