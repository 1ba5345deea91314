"""Who may talk to the viewer, and what its pages may run: one ASGI middleware.

:class:`Guard` wraps the whole app (NiceGUI's pages, its static files and its socket.io
endpoint, which NiceGUI mounts inside the same FastAPI app, so websocket and polling traffic
pass here too) and, for every HTTP request and websocket handshake:

- refuses a request that names this machine by a host name other than ``localhost`` while
  the viewer listens on loopback (a name of someone else's made to point at this machine,
  "DNS rebinding", would otherwise let their page read the viewer's);
- refuses one whose ``Origin`` is another site's, and one the browser marks as sent by
  another site (``Sec-Fetch-Site``) unless it is a plain navigation (a link followed):
  another site's page cannot fetch, post to, or open a socket to the viewer;
- with an access token (``--token``, and always beyond loopback), refuses a request that
  carries neither the token (``?token=``, or ``Authorization: token ...``) nor the cookie
  a first visit with the token set (``HttpOnly``, ``SameSite=Strict``; a visit with
  ``?token=`` is redirected to the same address without it, so the token leaves the address
  bar and the history);
- sets on every response a Content-Security-Policy (:func:`policy`) and the headers that
  keep the pages out of other sites' frames and their resources out of other sites' pages.

Starlette and NiceGUI have no such middleware: NiceGUI's authentication example is a
``BaseHTTPMiddleware`` over its session storage, which websocket handshakes pass by, and
neither sets a Content-Security-Policy (NiceGUI's page template takes no nonce, so the
policy allows the hashes of the page's own inline scripts, computed here per page). It is
written here as a plain ASGI middleware, which sees HTTP and websocket alike.
"""

from __future__ import annotations

import base64
import hashlib
import ipaddress
import re
import secrets
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any
from urllib.parse import unquote_plus, urlsplit

from starlette.datastructures import MutableHeaders
from starlette.requests import HTTPConnection
from starlette.responses import PlainTextResponse, RedirectResponse

__all__ = ["Guard", "cookie_name", "new_token", "policy", "refusal", "script_hashes"]

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]

BASE_POLICY = (
    "default-src 'self'",
    # NiceGUI needs eval: Vue compiles its components' templates in the browser, and
    # NiceGUI turns ':'-props into functions with new Function (docs/viewer.md)
    "script-src 'self' 'unsafe-eval'",
    "style-src 'self' 'unsafe-inline'",  # Quasar, Tailwind and Mermaid set inline styles
    "img-src 'self' data: blob:",
    "font-src 'self' data:",
    "connect-src 'self'",
    "object-src 'none'",
    "base-uri 'none'",
    "form-action 'self'",
    "frame-ancestors 'none'",
)
HEADERS = {
    "X-Frame-Options": "DENY",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cross-Origin-Opener-Policy": "same-origin",
    "Cross-Origin-Resource-Policy": "same-origin",
}
_SCRIPT = re.compile(rb"<script\b([^>]*)>(.*?)</script\s*>", re.IGNORECASE | re.DOTALL)
_SRC = re.compile(rb"\bsrc\s*=", re.IGNORECASE)
MAX_HTML_BYTES = 64 * 1024 * 1024  # a page larger than this is sent without inline scripts


def new_token() -> str:
    """A random access token (32 bytes, URL-safe), as Jupyter makes one."""
    return secrets.token_urlsafe(32)


def cookie_name(port: int) -> str:
    """The token's cookie: one per port (cookies are not told apart by port)."""
    return f"skillcompose-view-{port}"


def script_hashes(html: bytes) -> list[str]:
    """The CSP hashes (``'sha256-...'``) of the inline scripts of ``html``: the scripts
    NiceGUI's page template writes (the import map, the app's start with its elements).
    Text a page shows cannot add one: NiceGUI writes every value into those scripts as JSON
    with ``<``, ``>``, ``&``, backquote and ``$`` written as HTML references, so no value can
    close a script or open another."""
    out = []
    for attrs, body in _SCRIPT.findall(html):
        if _SRC.search(attrs):
            continue
        body = body.replace(b"\r\n", b"\n").replace(b"\r", b"\n")  # as the parser reads it
        digest = base64.b64encode(hashlib.sha256(body).digest()).decode("ascii")
        out.append(f"'sha256-{digest}'")
    return list(dict.fromkeys(out))


def policy(hashes: list[str] | None = None) -> str:
    """The Content-Security-Policy of a response: :data:`BASE_POLICY`, with the hashes of
    the page's own inline scripts allowed (no other inline script, no inline event handler,
    no script from another host)."""
    parts = list(BASE_POLICY)
    if hashes:
        parts[1] += " " + " ".join(hashes)
    return "; ".join(parts)


def _host_is_address(host_header: str) -> bool:
    host = urlsplit("//" + host_header).hostname or ""
    if host == "localhost":
        return True
    try:
        ipaddress.ip_address(host)
    except ValueError:
        return False
    return True


def _same(a: str, b: str) -> bool:
    return secrets.compare_digest(a.encode("utf-8", "replace"), b.encode("utf-8", "replace"))


def refusal(conn: HTTPConnection, *, token: str | None, cookie: str, remote: bool
            ) -> str | None:
    """Why the request ``conn`` is refused (None: it may go on); see the module's
    docstring. ``remote``: the viewer listens beyond loopback (host names allowed, the token
    required)."""
    headers = conn.headers
    host = headers.get("host", "")
    if not remote and not _host_is_address(host):
        return (f"this viewer answers only requests naming this machine by its address "
                f"(such as 127.0.0.1), not {host[:100]!r}")
    origin = headers.get("origin")
    if origin is not None and origin not in (f"http://{host}", f"https://{host}"):
        return "requests from another site's page are refused"
    site = headers.get("sec-fetch-site", "")
    if site in ("cross-site", "same-site") and not (  # a link followed may come in
            conn.scope["type"] == "http" and conn.scope.get("method") in ("GET", "HEAD")
            and headers.get("sec-fetch-mode", "navigate") == "navigate"):
        return "requests from another site's page are refused"
    if token is None:
        return None
    given = [conn.cookies.get(cookie, ""), conn.query_params.get("token", "")]
    auth = headers.get("authorization", "")
    if auth[:6].lower() == "token " or auth[:7].lower() == "bearer ":
        given.append(auth.split(" ", 1)[1].strip())
    if any(g and _same(g, token) for g in given):
        return None
    return ("this viewer needs its access token: open the address it printed when it "
            "started (it ends in ?token=...)")


class Guard:
    """The ASGI middleware of the module's docstring."""

    def __init__(self, app: Callable[[Scope, Receive, Send], Awaitable[None]], *,
                 token: str | None = None, cookie: str = "skillcompose-view",
                 remote: bool = False) -> None:
        self.app = app
        self.token = token
        self.cookie = cookie
        self.remote = remote

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        conn = HTTPConnection(scope)
        why = refusal(conn, token=self.token, cookie=self.cookie, remote=self.remote)
        if why is not None:
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008})
                return
            await PlainTextResponse(f"skillcompose view: {why}\n", 403)(
                scope, receive, _with_headers(send))
            return
        if (self.token is not None and scope["type"] == "http"
                and scope.get("method") in ("GET", "HEAD") and "token" in conn.query_params
                and _same(conn.query_params["token"], self.token)):
            await self._redirect_with_cookie(conn)(scope, receive, _with_headers(send))
            return
        await self.app(scope, receive, _with_headers(send) if scope["type"] == "http"
                       else send)

    def _redirect_with_cookie(self, conn: HTTPConnection) -> RedirectResponse:
        raw = conn.scope.get("query_string", b"").decode("latin-1")
        query = "&".join(part for part in raw.split("&")  # the others as they came
                         if part and unquote_plus(part.split("=", 1)[0]) != "token")
        path = "/" + conn.scope["path"].lstrip("/\\")  # never "//host": an address elsewhere
        response = RedirectResponse(path + (f"?{query}" if query else ""), 303)
        assert self.token is not None
        response.set_cookie(self.cookie, self.token, httponly=True, samesite="strict",
                            path="/")
        return response


def _with_headers(send: Send) -> Send:
    """``send`` adding :data:`HEADERS` and the CSP to the response; an HTML page is held
    until it is whole, to hash its inline scripts."""
    start: Message | None = None
    chunks: list[bytes] = []

    async def wrapped(message: Message) -> None:
        nonlocal start
        if message["type"] == "http.response.start":
            headers = MutableHeaders(scope=message)
            for name, value in HEADERS.items():
                headers[name] = value
            is_html = headers.get("content-type", "").startswith("text/html") \
                and not headers.get("content-encoding")
            if not is_html:
                headers["Content-Security-Policy"] = policy()
                await send(message)
                return
            start = message
            return
        if message["type"] == "http.response.body" and start is not None:
            chunks.append(message.get("body", b""))
            if message.get("more_body", False) and sum(map(len, chunks)) < MAX_HTML_BYTES:
                return
            body = b"".join(chunks)
            chunks.clear()
            headers = MutableHeaders(scope=start)
            headers["Content-Security-Policy"] = policy(
                script_hashes(body) if len(body) < MAX_HTML_BYTES else None)
            await send(start)
            start = None
            await send({"type": "http.response.body", "body": body,
                        "more_body": message.get("more_body", False)})
            return
        await send(message)

    return wrapped
