"""A Ray cluster of several nodes on this one machine, for trying the Ray backend and for
testing it: :func:`local_cluster` starts a head node and more nodes joining it (``ray start
--block``, each with its own CPUs, its own temporary directory and its own ports, bound to
127.0.0.1), and stops them all on leaving. Each node's processes are known (a tag in
their environment), so :meth:`LocalCluster.kill` can take a node down in the middle of a
run, as a machine lost, and no process outlives the cluster. Linux only (``/proc``).

Needs the optional extra: ``pip install skillcompose[ray]``.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

from .errors import EvolutionError

__all__ = ["PRIVATE_NET", "LocalCluster", "local_cluster", "private_network"]


PRIVATE_NET = ["unshare", "--net", "sh", "-c", 'ip link set lo up && exec "$@"', "sh"]
"""A command prefix that runs a command in a network namespace of its own, loopback its
only interface: Ray listens on every interface (its versions we support offer no setting
that keeps it on 127.0.0.1), so our tests and benchmarks start their clusters in one."""


def private_network() -> bool:
    """Whether :data:`PRIVATE_NET` works here (``unshare`` and ``ip`` present, and the
    right to make a namespace: root)."""
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    return subprocess.run([*PRIVATE_NET, "true"], capture_output=True,
                          check=False).returncode == 0


def _free_ports(count: int) -> list[int]:
    """Ports nobody listens on now (held together, so they differ)."""
    socks = []
    try:
        for _ in range(count):
            s = socket.socket()
            s.bind(("127.0.0.1", 0))
            socks.append(s)
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


_TAG = "SKILLCOMPOSE_LOCAL_RAY_NODE"


def _tagged(prefix: str) -> dict[int, str]:
    """The processes of this machine whose environment has ``_TAG`` starting with
    ``prefix`` (every process of a node inherits it, whatever its process group), and
    the tag of each."""
    found: dict[int, str] = {}
    needle = f"{_TAG}={prefix}".encode()
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        try:
            with open(f"/proc/{entry}/environ", "rb") as f:
                env = f.read()
        except OSError:  # gone, or not ours to read
            continue
        for item in env.split(b"\0"):
            if item.startswith(needle):
                found[int(entry)] = item.split(b"=", 1)[1].decode()
    return found


@dataclass
class LocalCluster:
    """Nodes started by :func:`local_cluster`: the head's ``address``, what a driver's
    environment needs to connect (``env``: the cluster's own authentication token), and per
    node its ``ray start`` process and temporary directory. Each node's processes carry a
    tag of their own in their environment, by which they are found and stopped."""

    address: str
    tag: str
    env: dict[str, str] = field(default_factory=dict)
    processes: list[subprocess.Popen[bytes]] = field(default_factory=list)
    temp_dirs: list[str] = field(default_factory=list)

    def pids(self, node: int | None = None) -> list[int]:
        """The processes of node ``node`` (0 is the head), or of every node, still there."""
        prefix = f"{self.tag}-" if node is None else f"{self.tag}-{node}"
        return sorted(pid for pid, tag in _tagged(prefix).items()
                      if node is None or tag == prefix)

    def kill(self, node: int) -> None:
        """Kill node ``node`` (0 is the head) and every process it started, at once, as
        a machine lost."""
        for pid in self.pids(node):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        self.processes[node].wait()

    def stop(self) -> None:
        """Stop every node (politely, then by force) and remove the temporary directories."""
        for proc in reversed(self.processes):
            with contextlib.suppress(ProcessLookupError):
                proc.terminate()
        deadline = time.monotonic() + 10
        while self.pids() and time.monotonic() < deadline:
            time.sleep(0.2)
        for _ in range(50):  # the killed ones are reaped after a moment
            left = self.pids()
            if not left:
                break
            for pid in left:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
            time.sleep(0.1)
        for proc in self.processes:
            proc.wait()
        for d in self.temp_dirs:
            shutil.rmtree(d, ignore_errors=True)


def _node_command(python: str, cpus: int, temp_dir: str, head: str | None) -> list[str]:
    ports = _free_ports(7)
    cmd = [python, "-m", "ray.scripts.scripts", "start", "--block",
           "--num-cpus", str(cpus), "--num-gpus", "0",
           "--node-ip-address", "127.0.0.1", "--temp-dir", temp_dir,
           "--node-manager-port", str(ports[0]), "--object-manager-port", str(ports[1]),
           "--dashboard-agent-listen-port", str(ports[2]),
           "--dashboard-agent-grpc-port", str(ports[3]),
           "--metrics-export-port", str(ports[4]), "--runtime-env-agent-port", str(ports[5]),
           "--object-store-memory", str(100 * 2**20), "--disable-usage-stats"]
    if head is None:
        cmd += ["--head", "--port", str(ports[6]), "--include-dashboard=false"]
    else:
        cmd += ["--address", head]
    return cmd


def _wait_for(count: int, address: str, python: str, env: Mapping[str, str], cwd: str,
              timeout: float, node: subprocess.Popen[bytes], log: str) -> None:
    """Wait until ``count`` nodes are alive in the cluster at ``address``; ``node`` is the
    last one started (``log``: its output)."""
    deadline = time.monotonic() + timeout

    def exited() -> None:
        if node.poll() is not None:
            with open(log, errors="replace") as f:
                tail = f.read()[-600:]
            raise EvolutionError(f"a local Ray node exited with code {node.returncode}: {tail}")

    host, port = address.rsplit(":", 1)
    while True:  # the head's port first: connecting to a cluster not yet there hangs
        with contextlib.suppress(OSError), socket.create_connection((host, int(port)), 1):
            break
        exited()
        if time.monotonic() > deadline:
            raise EvolutionError(f"the local Ray head at {address} did not start in "
                                 f"{timeout:g} s")
        time.sleep(0.2)
    probe = ("import sys, ray; ray.init(address=sys.argv[1], log_to_driver=False); "
             "print(sum(n['Alive'] for n in ray.nodes()))")
    error = ""
    while time.monotonic() < deadline:
        try:
            done = subprocess.run([python, "-c", probe, address], capture_output=True,
                                  text=True, env=dict(env), cwd=cwd, check=False,
                                  timeout=max(1.0, min(30.0, deadline - time.monotonic())))
        except subprocess.TimeoutExpired:
            continue
        alive = done.stdout.strip().splitlines()[-1:] if done.returncode == 0 else []
        if alive and int(alive[0]) >= count:
            return
        error = done.stderr.strip()[-500:]
        exited()
        time.sleep(0.5)
    raise EvolutionError(
        f"the local Ray cluster at {address} did not reach {count} nodes in {timeout:g} s"
        + (f": {error}" if error else "")
    )


@contextlib.contextmanager
def local_cluster(
    nodes: int = 2, cpus_per_node: int = 1, *, python: str | None = None,
    env: Mapping[str, str] | None = None, timeout: float = 120.0,
) -> Iterator[LocalCluster]:
    """A Ray cluster of ``nodes`` nodes on this machine, bound to 127.0.0.1, stopped on
    leaving however the block ends.

    ``python`` and ``env`` are the interpreter and environment the nodes (and so their
    workers) run with: by default this one's. A test gives an interpreter and an
    environment in which this project cannot be imported, to show that what the workers
    run reaches them through Ray's runtime environment alone.
    """
    python = python or sys.executable
    run_env = dict(os.environ if env is None else env)
    run_env.pop("RAY_ADDRESS", None)
    cluster = LocalCluster(address="", tag=secrets.token_hex(8),
                           env={"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)})
    run_env.update(cluster.env)
    cwd = tempfile.mkdtemp(prefix="rc")
    cluster.temp_dirs.append(cwd)
    try:
        for k in range(nodes):
            temp_dir = tempfile.mkdtemp(prefix=f"r{k}")
            cluster.temp_dirs.append(temp_dir)
            cmd = _node_command(python, cpus_per_node, temp_dir,
                                cluster.address if k else None)
            if not k:
                cluster.address = f"127.0.0.1:{cmd[cmd.index('--port') + 1]}"
            log = os.path.join(temp_dir, "node.log")
            with open(log, "wb") as out:
                cluster.processes.append(subprocess.Popen(
                    cmd, env={**run_env, _TAG: f"{cluster.tag}-{k}"}, cwd=cwd,
                    stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                    start_new_session=True,
                ))
            _wait_for(k + 1, cluster.address, python, run_env, cwd, timeout,
                      cluster.processes[-1], log)
        yield cluster
    finally:
        cluster.stop()
