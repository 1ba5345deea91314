"""A direct connection from the Ray evaluator to each of its actors, for the jobs and their
results.

Why by hand: a Ray actor call costs the driver about 1 ms of CPU and leaves the actor idle
for 1 to 2 ms before its first job and after its last, which on a generation of 20 ms per
actor is a tenth of the work; Ray's compiled graphs, its own answer to that, poll their
channels and so keep the shared cores busy while they wait (see "Running on a Ray
cluster" in docs/evolve.md). Over a connection of this module the same chunk costs what a
process pool's pipe does. Ray still places the actors, ships the code, starts and kills
them and tells when one died; only the chunks and their results take this path.

The connection is the standard library's (``multiprocessing.connection``: framed pickled
messages, and its HMAC challenge both ways with a key the driver hands each actor through
Ray, so nothing that does not hold the key can make an actor unpickle a byte), over TCP
with Nagle's algorithm off (a chunk sent as a header and a body otherwise waits for the
peer's delayed acknowledgement: 40 ms a round trip). An actor on the driver's own node
listens on 127.0.0.1 only. Linux and macOS.
"""

from __future__ import annotations

import contextlib
import queue
import socket
import struct
import threading
import time
from collections.abc import Iterator
from multiprocessing.connection import Connection, answer_challenge, deliver_challenge
from typing import Any

__all__ = ["HANDSHAKE_S", "JobServer", "connect", "messages"]

HANDSHAKE_S = 10.0
"""The longest an actor lets a peer take over the challenge before it drops it and takes
the next; the evaluator waits three times as long for its own, so that one stranger in the
way does not keep it out."""


def _bound(conn: Connection | socket.socket, seconds: float) -> None:
    """Make blocking reads and writes on ``conn`` fail after ``seconds`` (0: never)."""
    sock = conn if isinstance(conn, socket.socket) else socket.socket(fileno=conn.fileno())
    try:
        whole = int(seconds)
        tv = struct.pack("ll", whole, int((seconds - whole) * 1e6))
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, tv)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, tv)
    finally:
        if sock is not conn:
            sock.detach()  # the fd stays the connection's


@contextlib.contextmanager
def _deadline(conn: Connection, seconds: float) -> Iterator[None]:
    """The whole handshake within ``seconds``: past it the socket is shut down and the read
    or write in progress fails. The bound of :func:`_bound` is per read, so a peer sending a
    byte every few seconds could hold the handshake for as long as it liked."""
    lock = threading.Lock()
    done = False

    def expire() -> None:
        with lock:
            if done:
                return
            sock = socket.socket(fileno=conn.fileno())
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            finally:
                sock.detach()

    timer = threading.Timer(seconds, expire)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        with lock:
            done = True
        timer.cancel()


def _connection(sock: socket.socket, bound: float) -> Connection:
    """``sock`` (connected) as a blocking connection without Nagle's delay, its reads and
    writes bounded by ``bound`` seconds until :func:`_bound` lifts that."""
    sock.settimeout(None)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    _bound(sock, bound)
    return Connection(sock.detach())


def connect(address: tuple[str, int], key: bytes) -> Connection:
    """The evaluator's end of a connection to the actor listening at ``address``, both
    sides proven to hold ``key``. Raises ``OSError`` (refused, unreachable, timed out),
    ``EOFError`` (the actor went away) or ``multiprocessing.AuthenticationError``."""
    conn = _connection(socket.create_connection(address, timeout=HANDSHAKE_S),
                       3 * HANDSHAKE_S)
    try:
        with _deadline(conn, 3 * HANDSHAKE_S):
            answer_challenge(conn, key)
            deliver_challenge(conn, key)
        _bound(conn, 0)
    except BaseException:
        conn.close()
        raise
    return conn


class JobServer:
    """The actor's end: a socket listening on ``host`` (an ephemeral port), then the one
    connection that proves it holds ``key``."""

    def __init__(self, host: str, key: bytes) -> None:
        self._key = key
        self._server: socket.socket | None = socket.create_server((host, 0))
        self.address: tuple[str, int] = self._server.getsockname()[:2]

    def accept(self, timeout: float) -> Connection:
        """The evaluator's connection, within ``timeout`` seconds: a peer that fails the
        challenge (or stalls in it) is dropped and the next one waited for. Stops
        listening once connected; raises ``TimeoutError`` when no peer passed in time."""
        assert self._server is not None, "accept() once"
        deadline = time.monotonic() + timeout
        try:
            while True:
                self._server.settimeout(max(0.001, deadline - time.monotonic()))
                sock, _ = self._server.accept()
                conn = _connection(sock, HANDSHAKE_S)
                try:
                    with _deadline(conn, HANDSHAKE_S):  # one deadline per connection
                        deliver_challenge(conn, self._key)
                        answer_challenge(conn, self._key)
                    _bound(conn, 0)
                    return conn
                except Exception:  # not the evaluator (or it went away): the next
                    conn.close()
                    if time.monotonic() >= deadline:
                        raise TimeoutError("no evaluator connected") from None
        finally:
            self._server.close()
            self._server = None


def messages(conn: Connection) -> Iterator[Any]:
    """What comes over ``conn`` until it closes, read by a thread of its own as it comes,
    so that a sender never waits on the reader being busy with the message before."""
    box: queue.SimpleQueue[tuple[bool, Any]] = queue.SimpleQueue()

    def read() -> None:
        while True:
            try:
                box.put((True, conn.recv()))
            except Exception:  # closed (by the evaluator, or under us), or garbled
                box.put((False, None))
                return

    threading.Thread(target=read, name="skillcompose-jobs", daemon=True).start()
    while True:
        more, message = box.get()
        if not more:
            return
        yield message
