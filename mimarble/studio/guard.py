"""Who may talk to the studio's server: the token, the ``Host`` and the ``Origin`` checked
on every request and websocket, before anything else runs.

The studio's server listens on a port of this machine, where any local program and any
web page the user's browser opens could reach it. Three checks keep them out, as
Jupyter's server does:

* **the token** — 32 random bytes (:func:`secrets.token_urlsafe`), in the URL the studio
  prints; every request and websocket carries it (``?token=…``), compared in constant
  time (:func:`secrets.compare_digest`). A page on another site cannot read it.
* **the Host header** — must name this server (``127.0.0.1:PORT``, ``localhost:PORT``,
  ``[::1]:PORT``, or the ``--host`` the user gave): a page on an attacker's domain that
  resolves to 127.0.0.1 (DNS rebinding) sends its own domain as the Host and is refused.
* **the Origin header** — when the browser sends one (it always does for a websocket and
  for a cross-site request), it must be this server itself: another site's page cannot
  post to it or open its websocket even with a stolen token.

:class:`Guard` is an ASGI middleware: a refused HTTP request gets 403 and one sentence,
a refused websocket is closed before it is accepted (the browser sees 403).
Standard library only.
"""

from __future__ import annotations

import secrets
from urllib.parse import parse_qs

#: The hosts that mean this machine, as a browser writes them in Host and Origin.
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")


def new_token() -> str:
    """A fresh random token (32 bytes, URL-safe base64: 43 characters)."""
    return secrets.token_urlsafe(32)


def host_names(host: str, port: int) -> frozenset:
    """Every ``name:port`` a Host header of this server may hold: the loopback names, and
    the host the server was bound to (``--host``), written as a browser writes it."""
    names = set(LOOPBACK_NAMES)
    if host not in ("0.0.0.0", "::", ""):
        names.add(f"[{host}]" if ":" in host and not host.startswith("[") else host)
    return frozenset(f"{name}:{port}".lower() for name in names)


class Guard:
    """ASGI middleware: lets through only requests and websockets that carry ``token`` and
    whose ``Host`` (and ``Origin``, when sent) is this server.

    ========== ===============================================================
    Parameter  Meaning
    ========== ===============================================================
    app        the ASGI application behind the guard
    token      the secret every request must carry as ``?token=…``
    hosts      the ``name:port`` values a Host header may hold (:func:`host_names`)
    ========== ===============================================================
    """

    def __init__(self, app, token: str, hosts: frozenset):
        self.app = app
        self.token = token
        self.hosts = hosts
        self.origins = frozenset(f"http://{h}" for h in hosts)

    def problem(self, scope) -> str | None:
        """Why the request in ``scope`` is refused, in one sentence; None if it may pass."""
        headers = {}
        for name, value in scope.get("headers", ()):
            headers.setdefault(name.decode("latin-1").lower(), value.decode("latin-1"))
        host = headers.get("host", "").lower()
        if host not in self.hosts:
            return "this server answers requests for its own address only (the Host header is not it)"
        origin = headers.get("origin")
        if origin is not None and origin.lower() not in self.origins:
            return "this server answers its own page only (the Origin header is another site)"
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        given = query.get("token", [""])[0]
        if not secrets.compare_digest(given.encode(), self.token.encode()):
            return ("the studio's address needs its token: open the URL that "
                    "`mimarble studio` printed (with ?token=…)")
        return None

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)      # lifespan
        problem = self.problem(scope)
        if problem is None:
            return await self.app(scope, receive, send)
        if scope["type"] == "websocket":
            # Closing before accepting: the server answers the handshake with 403.
            await send({"type": "websocket.close", "code": 1008, "reason": problem[:120]})
            return
        body = (problem + "\n").encode()
        await send({"type": "http.response.start", "status": 403,
                    "headers": [(b"content-type", b"text/plain; charset=utf-8"),
                                (b"content-length", str(len(body)).encode()),
                                (b"cache-control", b"no-store")]})
        await send({"type": "http.response.body", "body": body})
