"""The direct connection between the Ray evaluator and its actors (no Ray needed)."""

from __future__ import annotations

import os
import socket
import struct
import threading
import time
from multiprocessing import AuthenticationError
from multiprocessing.connection import Connection
from typing import Any

import pytest

from skillcompose.evolve import channel
from skillcompose.evolve.channel import JobServer, connect, messages

KEY = b"k" * 32


def _serve(server: JobServer, seen: list[Any], timeout: float = 10.0) -> threading.Thread:
    """An actor's loop in a thread: every message comes back doubled."""

    def loop() -> None:
        with server.accept(timeout) as conn:
            for message in messages(conn):
                seen.append(message)
                conn.send(message * 2)

    thread = threading.Thread(target=loop)
    thread.start()
    return thread


def _nodelay(conn: Connection) -> int:
    sock = socket.socket(fileno=os.dup(conn.fileno()))
    with sock:
        return sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY)


def test_jobs_go_both_ways_in_order_and_sends_never_wait_on_the_actor() -> None:
    server = JobServer("127.0.0.1", KEY)
    assert server.address[0] == "127.0.0.1"
    seen: list[Any] = []
    thread = _serve(server, seen)
    conn = connect(server.address, KEY)
    big = b"x" * (8 << 20)  # more than a socket's buffers: read by the actor as it comes
    for message in (1, big, 3):
        conn.send(message)
    assert [conn.recv() for _ in range(3)] == [2, big * 2, 6]
    assert _nodelay(conn)  # else each chunk waits for the delayed acknowledgement
    conn.close()
    thread.join(5)
    assert not thread.is_alive() and seen == [1, big, 3]


def test_a_peer_without_the_key_is_refused_and_the_evaluator_still_gets_in() -> None:
    server = JobServer("127.0.0.1", KEY)
    seen: list[Any] = []
    thread = _serve(server, seen)
    with pytest.raises(AuthenticationError):
        connect(server.address, b"not the key")
    conn = connect(server.address, KEY)
    conn.send("job")
    assert conn.recv() == "jobjob"
    conn.close()
    thread.join(5)
    assert seen == ["job"]  # nothing of the stranger's


def test_a_peer_that_stalls_in_the_challenge_is_dropped_and_keeps_nobody_out(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(channel, "HANDSHAKE_S", 0.3)
    server = JobServer("127.0.0.1", KEY)
    seen: list[Any] = []
    thread = _serve(server, seen)
    with socket.create_connection(server.address) as stalled:
        stalled.settimeout(5)
        stalled.recv(1 << 16)  # the challenge; never answered
        conn = connect(server.address, KEY)  # waits behind the stranger, and gets in
        assert stalled.recv(1) == b""  # dropped after the handshake's bound
    conn.send(1)
    assert conn.recv() == 2
    conn.close()
    thread.join(5)


def test_a_peer_that_trickles_bytes_is_dropped_at_one_deadline_per_connection(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A byte every 0.2 s keeps each read within a 0.5 s per-read bound; the handshake as a
    whole still ends at its deadline, and the driver behind the stranger gets in."""
    monkeypatch.setattr(channel, "HANDSHAKE_S", 0.5)
    server = JobServer("127.0.0.1", KEY)
    seen: list[Any] = []
    thread = _serve(server, seen)
    with socket.create_connection(server.address) as trickling:
        trickling.settimeout(5)
        trickling.recv(1 << 16)  # the challenge
        trickling.sendall(struct.pack("!i", 200))  # an answer of 200 bytes is coming...
        started = time.monotonic()
        dropped = False
        for _ in range(40):  # up to 8 s of trickling, far past the deadline
            try:
                trickling.sendall(b"\x00")
            except OSError:
                dropped = True
                break
            time.sleep(0.2)
            trickling.setblocking(False)
            try:
                if trickling.recv(1) == b"":
                    dropped = True
                    break
            except BlockingIOError:
                pass
            finally:
                trickling.setblocking(True)
        assert dropped and time.monotonic() - started < 3.0
    conn = connect(server.address, KEY)
    conn.send(1)
    assert conn.recv() == 2
    conn.close()
    thread.join(5)


def test_an_actor_nobody_connects_to_stops_listening() -> None:
    server = JobServer("127.0.0.1", KEY)
    with pytest.raises(TimeoutError):
        server.accept(0.2)
    with pytest.raises(ConnectionRefusedError):
        connect(server.address, KEY)
