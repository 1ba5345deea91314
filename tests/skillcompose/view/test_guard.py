"""Who may talk to the viewer: the access token (checked on pages, files and socket.io
traffic), the Host, Origin and fetch-metadata checks, the Content-Security-Policy, and the
command line that asks for a token and refuses an address beyond this machine without
``--allow-remote``. Tests connect only to 127.0.0.1 (or to the app in this process)."""

from __future__ import annotations

import asyncio
import base64
import hashlib
import re
import urllib.error
import urllib.request
from collections.abc import MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from starlette.applications import Starlette
from starlette.responses import HTMLResponse, PlainTextResponse
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket

from skillcompose.arguments import UsageError
from skillcompose.cli import main
from skillcompose.view import cli as view_cli
from skillcompose.view.guard import Guard, policy, script_hashes

from .conftest import REPO, Page, start_viewer, wait_for

TOKEN = "s3cret-token"
PAGE = ('<html><head><script type="importmap">{"imports": {}}</script></head><body>'
        '<script src="/static/x.js"></script><script type="module">start(`a&lt;b`)</script>'
        "</body></html>")


@dataclass
class Answer:
    status: int
    headers: dict[str, str]
    text: str
    messages: list[dict[str, Any]]


class Client:
    """Requests to the guarded app, in this process (ASGI messages; no network)."""

    def __init__(self, token: str | None = TOKEN, remote: bool = False) -> None:
        async def page(request: Any) -> HTMLResponse:
            return HTMLResponse(PAGE)

        async def data(request: Any) -> PlainTextResponse:
            return PlainTextResponse("data")

        async def socket(ws: WebSocket) -> None:
            await ws.accept()
            await ws.send_text("hello")
            await ws.close()

        inner = Starlette(routes=[Route("/", page, methods=["GET", "POST"]),
                                  Route("/data", data, methods=["GET", "POST"]),
                                  WebSocketRoute("/_nicegui_ws/socket.io/", socket)])
        self.app = Guard(inner, token=token, cookie="view-1", remote=remote)
        self.cookie = ""

    def get(self, target: str, headers: dict[str, str] | None = None, *,
            method: str = "GET", websocket: bool = False) -> Answer:
        path, _, query = target.partition("?")
        sent = {"host": "127.0.0.1:8765"} | ({"cookie": self.cookie} if self.cookie else {})
        scope = {"type": "websocket" if websocket else "http", "method": method,
                 "path": path, "raw_path": path.encode(), "query_string": query.encode(),
                 "root_path": "", "scheme": "http", "http_version": "1.1",
                 "server": ("127.0.0.1", 8765), "client": ("127.0.0.1", 50000),
                 "asgi": {"version": "3.0"},
                 "headers": [(k.lower().encode(), v.encode())
                             for k, v in (sent | (headers or {})).items()]}
        incoming = [{"type": "websocket.connect"} if websocket else
                    {"type": "http.request", "body": b"", "more_body": False}]
        messages: list[dict[str, Any]] = []

        async def receive() -> dict[str, Any]:
            return incoming.pop(0) if incoming else {
                "type": "websocket.disconnect" if websocket else "http.disconnect"}

        async def send(message: MutableMapping[str, Any]) -> None:
            messages.append(dict(message))

        asyncio.run(self.app(scope, receive, send))
        start = next((m for m in messages if m["type"] == "http.response.start"), {})
        answer = Answer(start.get("status", 0), {k.decode(): v.decode() for k, v in
                                                 start.get("headers", [])},
                        b"".join(m.get("body", b"") for m in messages).decode(), messages)
        if "set-cookie" in answer.headers:
            self.cookie = answer.headers["set-cookie"].split(";")[0]
        return answer

    def socket(self, target: str = "/_nicegui_ws/socket.io/",
               headers: dict[str, str] | None = None) -> list[Any]:
        """What the socket endpoint answered: its messages' types (and a close's code)."""
        return [m.get("code", m["type"]) if m["type"] == "websocket.close" else m["type"]
                for m in self.get(target, headers, websocket=True).messages]


def test_without_a_token_on_loopback_pages_are_served_with_the_policy() -> None:
    client = Client(token=None)
    r = client.get("/")
    assert r.status == 200
    csp = r.headers["content-security-policy"].split("; ")
    script = csp[1].split()
    assert script[:3] == ["script-src", "'self'", "'unsafe-eval'"]
    inline = [b'{"imports": {}}', b"start(`a&lt;b`)"]
    assert sorted(script[3:]) == sorted(
        f"'sha256-{base64.b64encode(hashlib.sha256(s).digest()).decode()}'" for s in inline)
    assert "'unsafe-inline'" not in csp[1] and "frame-ancestors 'none'" in csp
    for name, value in (("x-frame-options", "DENY"), ("x-content-type-options", "nosniff"),
                        ("referrer-policy", "no-referrer"),
                        ("cross-origin-resource-policy", "same-origin")):
        assert r.headers[name] == value
    assert client.get("/data").headers["content-security-policy"] == policy()
    assert client.socket() == ["websocket.accept", "websocket.send", 1000]


def test_a_script_a_value_could_add_is_not_hashed() -> None:
    html = (b'<script>app(String.raw`{"t": "&lt;/script&gt;&lt;script&gt;x()"}`)</script>'
            b"<div>&lt;script&gt;evil()&lt;/script&gt;</div>")
    assert len(script_hashes(html)) == 1  # the app's own script only


def test_the_token_is_needed_for_pages_files_and_sockets() -> None:
    client = Client()
    for path in ("/", "/data", "/?token=wrong"):
        r = client.get(path)
        assert r.status == 403 and "access token" in r.text
        assert r.headers["x-frame-options"] == "DENY"
    assert client.socket() == [1008]  # refused before it is accepted
    r = client.get(f"/?a=1&token={TOKEN}&b=2")  # the printed address: a cookie, then away
    assert r.status == 303 and r.headers["location"] == "/?a=1&b=2"
    cookie = r.headers["set-cookie"]
    assert f"view-1={TOKEN}" in cookie and "HttpOnly" in cookie
    assert "samesite=strict" in cookie.lower()
    assert client.get("/data").status == 200  # the cookie, from now on
    assert client.socket()[0] == "websocket.accept"
    fresh = Client()
    assert fresh.get("/data", {"Authorization": f"token {TOKEN}"}).status == 200
    assert fresh.socket(f"/_nicegui_ws/socket.io/?token={TOKEN}")[0] == "websocket.accept"
    r = fresh.get(f"//evil.example/?token={TOKEN}")  # never a redirect to another host
    assert r.status == 303 and r.headers["location"] == "/evil.example/"


def test_host_names_other_sites_and_origins_are_refused() -> None:
    client = Client(token=None)
    r = client.get("/", {"host": "rebound.example.com:8765"})  # DNS rebinding
    assert r.status == 403 and "address" in r.text
    assert client.get("/", {"host": "localhost:8765"}).status == 200
    assert client.get("/", {"host": "[::1]:8765"}).status == 200
    r = client.get("/data", {"origin": "http://evil.example"})
    assert r.status == 403 and "another site" in r.text
    assert client.get("/data", {"origin": "http://127.0.0.1:8765"}).status == 200
    assert client.get("/data", {"sec-fetch-site": "cross-site",
                                "sec-fetch-mode": "cors"}).status == 403
    assert client.get("/data", {"sec-fetch-site": "same-site", "sec-fetch-mode": "navigate"},
                      method="POST").status == 403
    r = client.get("/", {"sec-fetch-site": "cross-site", "sec-fetch-mode": "navigate"})
    assert r.status == 200  # a link followed from elsewhere opens the page
    assert client.socket(headers={"origin": "http://evil.example"}) == [1008]
    assert client.socket(headers={"host": "rebound.example.com"}) == [1008]
    remote = Client(remote=True)  # beyond loopback: any name, but the token
    assert remote.get("/data", {"host": "box.lan:8765"}).status == 403
    assert remote.get("/data", {"host": "box.lan:8765",
                                "authorization": f"token {TOKEN}"}).status == 200


def test_an_address_beyond_this_machine_needs_allow_remote(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    def no_bind(host: str, port: int) -> None:
        raise AssertionError(f"the test would have bound {host}:{port}")

    monkeypatch.setattr(view_cli, "_check_port", no_bind)  # nothing is bound, ever
    for host in ("0.0.0.0", "::", "192.168.1.4"):
        assert main(["view", str(tmp_path), "--host", host]) == 2
        err = capsys.readouterr().err
        assert f"--host {host}" in err and "--allow-remote" in err and "\n" not in err.strip()
    assert view_cli.serving("0.0.0.0", True, False) == (True, True)  # a token, always
    assert view_cli.serving("127.0.0.1", False, False) == (False, False)
    assert view_cli.serving("127.0.0.1", False, True) == (False, True)
    assert view_cli.serving("::1", False, False) == (False, False)
    with pytest.raises(UsageError):
        view_cli.serving("::", False, True)


def _status(url: str, headers: dict[str, str] | None = None) -> int:
    opener = urllib.request.build_opener(NoRedirect)
    try:
        with opener.open(urllib.request.Request(url, headers=headers or {}), timeout=60) as r:
            return int(r.status)
    except urllib.error.HTTPError as exc:
        return exc.code


class NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args: Any, **kwargs: Any) -> None:
        return None


@pytest.mark.slow
@pytest.mark.browser
def test_a_viewer_with_a_token(tmp_path: Path, page: Page) -> None:
    """``--token`` on 127.0.0.1: the printed address opens the pages (and their live
    updates, over socket.io); without the token, or with another, nothing is served: no
    page, no script, no socket.io handshake."""
    (tmp_path / "pour.fsa.yaml").write_text(
        (REPO / "examples" / "pour_water_reference.fsa.yaml").read_text())
    viewer = start_viewer([str(tmp_path), "--token"], tmp_path / "view.log", REPO,
                          ready_status=403)
    try:
        printed = wait_for(lambda: re.search(r"on (http://127\.0\.0\.1:\d+/\?token=(\S+)) ",
                                             viewer.log.read_text()), what="the address")
        address, token = printed.group(1), printed.group(2)
        socket_io = "/_nicegui_ws/socket.io/?EIO=4&transport=polling"
        for path in ("/", "/fsa", f"/?token={token}x", socket_io, "/_nicegui/x/static/x.js"):
            assert _status(viewer.url + path) == 403, path
        assert _status(viewer.url + "/", {"Authorization": f"token {token}"}) == 200
        page.goto(address)
        assert "token" not in page.page.url  # redirected away from the address bar
        wait_for(lambda: page.page.get_by_test_id("run-count").inner_text() == "0 run(s)",
                 what="the runs page's timer (over its socket)")
        page.goto(viewer.url + "/fsa")  # the cookie, on the next pages
        wait_for(lambda: page.page.locator("[data-testid=fsa-graph] svg").count(),
                 what="the graph")
        assert page.errors == []
    finally:
        code, text = viewer.stop()
    assert code in (0, 130) and "Traceback" not in text, text
