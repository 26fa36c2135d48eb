"""The studio's web server: the page, its static files and one websocket per tab, over a
:class:`~mimarble.studio.StudioSession` (the engine: edits → frames).

Starlette routes the requests and uvicorn serves them (docs/design-decisions.md, "Marble
studio's server and page (issue 41)", says why these and what they were measured
against). The server runs its own asyncio loop in a background thread
(:meth:`StudioServer.start`), so the command line and a Jupyter kernel use it alike.

Data flow:

* page → server: JSON messages (mimarble/studio/messages.py), each checked, then handed
  to the session (an edit, an orbit, save, …); every one gets an answer (``edited``,
  ``invalid`` with the parameter table's sentence, ``done``, ``problem``);
* server → page: the session's events (from its render thread, handed over to the loop):
  frames as binary messages (:func:`~mimarble.studio.messages.frame_message`), state,
  controls, compare results. Each tab has a mailbox that keeps only the **latest** of each
  kind: a tab that reads slowly gets the newest frame, never a queue of stale ones; its
  answers are bounded (:data:`MAX_ANSWERS`): while that many wait, the server reads no
  more of that tab's messages, so a tab that sends without reading holds a bounded queue;
* an edit from one tab is shown by every other (``value`` messages; ``controls`` after an
  edit that changes their structure): the last edit wins everywhere.

Security: :class:`~mimarble.studio.guard.Guard` checks token, Host and Origin on every
request and websocket; the routes read only the page's own files (a fixed list), and
write only through the session (the opened scene, and the paths the user types for
Save as / Snapshot / Export).
"""

from __future__ import annotations

import asyncio
import collections
import json
import socket
import sys
import threading
import time
from pathlib import Path

from starlette.applications import Starlette
from starlette.responses import HTMLResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from mimarble.studio import messages
from mimarble.studio.errors import StudioError
from mimarble.studio.guard import LOOPBACK_NAMES, Guard, host_names, new_token

#: The page's files, read from the package (the only files a request can get).
STATIC = Path(__file__).resolve().parent / "static"
#: Each static file's name and its media type: a fixed list, so no request names a file.
STATIC_TYPES = {"studio.js": "text/javascript; charset=utf-8",
                "studio.css": "text/css; charset=utf-8"}
#: The kinds of control whose edit sets that control alone: the other tabs are sent its
#: value at once (other kinds, and structural edits, send every control).
_VALUE_KINDS = ("number", "integer", "choice", "boolean", "colour", "vector")
#: How soon after an edit every tab gets every control's value again (seconds).
CONTROLS_DELAY = 0.25
#: Answers waiting to be sent to one tab before the server stops reading its messages
#: (each message gets one answer): what a tab that sends without reading can make the
#: server hold.
MAX_ANSWERS = 64
#: The page's Content-Security-Policy: its own scripts and styles only, images from the
#: frames' blobs, the websocket back to this server; nothing from elsewhere.
CSP = ("default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; "
       "connect-src 'self'; base-uri 'none'; form-action 'none'")


class _Mailbox:
    """What the server has to send one tab: answers in order, and the latest message of
    each coalesced kind (frame, state, controls, compare) — a newer one replaces an unsent
    older one, so a slow tab is never behind by more than one frame. ``room`` is clear
    while :data:`MAX_ANSWERS` answers wait: the reader of the tab's messages waits on it."""

    def __init__(self, websocket: WebSocket):
        self.websocket = websocket
        self.answers = collections.deque()
        self.latest: dict = {}
        self.wake = asyncio.Event()
        self.room = asyncio.Event()
        self.room.set()

    def answer(self, message) -> None:
        self.answers.append(message)
        if len(self.answers) >= MAX_ANSWERS:
            self.room.clear()
        self.wake.set()

    async def wait_room(self, pump: asyncio.Future) -> bool:
        """Wait until fewer than :data:`MAX_ANSWERS` answers wait: True; False if the
        ``pump`` sending them ended first (a send failed: the tab is gone, and no send
        will make room)."""
        room = asyncio.ensure_future(self.room.wait())
        await asyncio.wait({room, pump}, return_when=asyncio.FIRST_COMPLETED)
        if not room.done():
            room.cancel()
            return False
        return True

    def put(self, kind: str, message) -> None:
        self.latest[kind] = message
        self.wake.set()

    async def pump(self) -> None:
        """Send what is in the mailbox, as it comes, until the tab goes away."""
        while True:
            await self.wake.wait()
            self.wake.clear()
            while self.answers or self.latest:
                if self.answers:
                    message = self.answers.popleft()
                    if len(self.answers) < MAX_ANSWERS:
                        self.room.set()
                else:
                    message = self.latest.pop(next(iter(self.latest)))
                if isinstance(message, bytes):
                    await self.websocket.send_bytes(message)
                else:
                    await self.websocket.send_text(json.dumps(message))


class StudioServer:
    """The studio's HTTP and websocket server over one session.

    ========== ===============================================================
    Parameter  Meaning
    ========== ===============================================================
    session    the :class:`~mimarble.studio.StudioSession` the page drives
    host       the address to listen on (default 127.0.0.1: this machine only)
    port       the port (0: a free one, chosen by the system)
    token      the secret of the URL (default: :func:`~mimarble.studio.guard.new_token`)
    ========== ===============================================================

    The socket is bound in the constructor (an ``OSError`` when the port is taken), so
    :attr:`url` is known before :meth:`start`.
    """

    def __init__(self, session, host: str = "127.0.0.1", port: int = 0, token: str | None = None):
        self.session = session
        self.host = host
        self.token = token or new_token()
        self._socket = _bind(host, port)
        self.port = self._socket.getsockname()[1]
        hosts = host_names(host, self.port)
        if host in ("0.0.0.0", "::"):
            hosts |= host_names(socket.gethostname(), self.port) | frozenset(
                f"{address}:{self.port}" for address in _addresses())
        self.app = Guard(self._routes(), self.token, hosts)
        self.clients: set = set()
        self.loop: asyncio.AbstractEventLoop | None = None
        self._server = None
        self._thread: threading.Thread | None = None
        self._unsubscribe = None
        self._kinds: dict = {}
        self._controls_due = False

    # ---- addresses -------------------------------------------------------------------

    @property
    def url(self) -> str:
        """The page's address with its token: what the user opens."""
        name = self.host if self.host not in ("0.0.0.0", "::", "") else "127.0.0.1"
        name = f"[{name}]" if ":" in name else name
        return f"http://{name}:{self.port}/?token={self.token}"

    # ---- running ---------------------------------------------------------------------

    def start(self, timeout: float = 30.0) -> "StudioServer":
        """Serve in a background thread (its own asyncio loop); returns once it listens."""
        import uvicorn
        config = uvicorn.Config(self.app, log_level="warning", lifespan="off",
                                ws="websockets-sansio", ws_max_size=messages.MAX_WIRE_BYTES,
                                timeout_graceful_shutdown=2, access_log=False)
        self._server = uvicorn.Server(config)
        ready = threading.Event()

        def serve():
            self.loop = asyncio.new_event_loop()
            asyncio.set_event_loop(self.loop)
            self.loop.call_soon(ready.set)
            try:
                self.loop.run_until_complete(self._server.serve(sockets=[self._socket]))
            finally:
                self.loop.close()

        self._unsubscribe = self.session.subscribe(self._event)
        self._thread = threading.Thread(target=serve, name="mimarble-studio-server", daemon=True)
        self._thread.start()
        ready.wait(timeout)
        deadline = time.monotonic() + timeout
        while not self._server.started and self._thread.is_alive() \
                and time.monotonic() < deadline:
            threading.Event().wait(0.01)
        if not self._server.started:
            self.stop()
            raise OSError(f"the studio's server did not start on {self.host}:{self.port}")
        return self

    def stop(self, timeout: float = 10.0) -> None:
        """Close every tab's websocket, stop serving and join the thread; idempotent."""
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        self._socket.close()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    # ---- the session's events (render thread → loop) -----------------------------------

    def _event(self, kind: str, payload) -> None:
        """The session's callback: hand the event over to the loop (never block here)."""
        loop = self.loop
        if loop is not None and not loop.is_closed():
            try:
                loop.call_soon_threadsafe(self._broadcast, kind, payload)
            except RuntimeError:                 # the loop closed meanwhile
                pass

    def _broadcast(self, kind: str, payload) -> None:
        if kind == "frame":
            message = messages.frame_message(dict(payload.meta(), type="frame"), payload.image)
            for client in self.clients:
                client.put("frame", message)
        elif kind == "compare":
            self._put_all("compare", compare_message(payload))
        elif kind == "reload":
            self._send_controls()
            self._put_all("reload", dict(payload, type="reload"))
        else:
            self._put_all(kind, {"type": kind, kind: payload})

    def _put_all(self, kind: str, message, but=None) -> None:
        for client in self.clients:
            if client is not but:
                client.put(kind, message)

    def _send_controls(self) -> None:
        self._controls_due = False
        controls = self._read_controls()
        self._put_all("controls", {"type": "controls", "controls": controls})

    def _read_controls(self) -> dict:
        """The session's controls, and each key's kind (what an edit of it refreshes)."""
        controls = self.session.controls()
        self._kinds = {c["key"]: ("structural" if c.get("structural") else c["kind"])
                       for group in controls["groups"] for c in group["controls"]}
        return controls

    def _refresh_controls(self, delay: float) -> None:
        """Send every tab the controls after ``delay`` seconds, once however many edits
        ask meanwhile (controls() takes ~2 ms and ~50 kB: not one per slider step)."""
        if not self._controls_due:
            self._controls_due = True
            asyncio.get_running_loop().call_later(delay, self._send_controls)

    # ---- the routes --------------------------------------------------------------------

    def _routes(self) -> Starlette:
        return Starlette(routes=[Route("/", self._index),
                                 Route("/static/{name}", self._static),
                                 WebSocketRoute("/ws", self._websocket)])

    async def _index(self, request):
        page = (STATIC / "index.html").read_text(encoding="utf-8")
        # The token reaches the page's script through a meta tag (the CSP allows no inline
        # script); asset URLs carry it as every request must.
        page = page.replace("{{token}}", self.token)
        return HTMLResponse(page, headers=_HEADERS)

    async def _static(self, request):
        name = request.path_params["name"]
        if name not in STATIC_TYPES:
            return Response("no such file\n", status_code=404, media_type="text/plain")
        return Response((STATIC / name).read_bytes(), media_type=STATIC_TYPES[name],
                        headers=_HEADERS)

    async def _websocket(self, websocket: WebSocket):
        await websocket.accept()
        client = _Mailbox(websocket)
        self.clients.add(client)
        pump = asyncio.ensure_future(client.pump())
        try:
            controls = self._read_controls()
            client.answer({"type": "hello", "controls": controls, "state": self.session.state(),
                           "presets": preset_list(),
                           "limits": {"message_bytes": messages.MAX_MESSAGE_BYTES}})
            frame = self.session.latest_frame()
            if frame is not None:
                client.put("frame", messages.frame_message(dict(frame.meta(), type="frame"),
                                                           frame.image))
            latest = getattr(self.session, "latest_histograms", lambda: None)()
            if latest is not None:
                client.put("histograms", {"type": "histograms", "histograms": latest})
            while True:
                if not client.room.is_set():      # a tab that does not read is not read
                    if not await client.wait_room(pump):
                        break                     # its sends failed: the tab is gone
                received = await websocket.receive()
                if received["type"] == "websocket.disconnect":
                    break
                text = received.get("text")
                if text is None:
                    text = received.get("bytes") or b""
                await self._handle(client, text)
        except WebSocketDisconnect:
            pass
        finally:
            self.clients.discard(client)
            pump.cancel()
            if pump.done() and not pump.cancelled():
                pump.exception()                  # a failed send: said by the tab's going

    # ---- the page's messages ------------------------------------------------------------

    async def _handle(self, client: _Mailbox, text) -> None:
        """Act on one message and answer it; nothing a message holds raises past here."""
        try:
            message = messages.parse(text)
        except messages.MessageError as e:
            client.answer({"type": "problem", "action": "message", "message": str(e)})
            return
        kind = message["type"]
        try:
            await getattr(self, f"_on_{kind}")(client, message)
        except Exception as e:                     # the server outlives any message
            client.answer({"type": "problem", "action": kind, "message": _sentence(e)})
            if not isinstance(e, (StudioError, ValueError, OSError, TypeError, KeyError)):
                print(f"mimarble studio: {kind}: {type(e).__name__}: {e}", file=sys.stderr)

    async def _on_edit(self, client, message):
        key, value, seq = message["key"], message["value"], message.get("seq")
        try:
            version = self.session.edit(key, value)
        except (ValueError, TypeError, KeyError) as e:
            client.answer({"type": "invalid", "key": key, "seq": seq, "message": _sentence(e)})
            return
        client.answer({"type": "edited", "key": key, "seq": seq, "version": version})
        if self._kinds.get(key) in _VALUE_KINDS:
            # The other tabs' control follows at once; every control (one key may set
            # others' values: marble.period sets each material's) within a quarter second.
            self._put_all(f"value {key}", {"type": "value", "key": key, "value": value},
                          but=client)
            self._refresh_controls(CONTROLS_DELAY)
        else:                    # structural, a ramp: the controls themselves may change
            self._refresh_controls(0.0)

    async def _on_orbit(self, client, message):
        self.session.orbit(message["dx"], message["dy"])

    async def _on_zoom(self, client, message):
        # The factor's limits are camera.ZOOM_LIMITS (zoomed_fov's ValueError, answered).
        self.session.zoom(message["factor"])

    async def _on_save(self, client, message):
        await _off_loop(self.session.save)
        client.answer({"type": "done", "action": "save",
                       "message": f"saved {self.session.state().get('path')}"})

    async def _on_save_as(self, client, message):
        path = self._user_path(message["path"])
        await _off_loop(self.session.save_as, path)
        self._send_controls()
        client.answer({"type": "done", "action": "save_as", "message": f"saved as {path}"})

    async def _on_snapshot(self, client, message):
        path = self._user_path(message["path"])
        await _off_loop(self.session.snapshot, path)
        client.answer({"type": "done", "action": "snapshot", "message": f"wrote {path}"})

    async def _on_export(self, client, message):
        path = self._user_path(message["path"])
        await _off_loop(self.session.export, path, python=message.get("python", False))
        client.answer({"type": "done", "action": "export", "message": f"exported {path}"})

    async def _on_compare(self, client, message):
        self.session.compare()
        client.answer({"type": "done", "action": "compare",
                       "message": "rendering the float64 reference…"})

    async def _on_reload(self, client, message):
        result = await _off_loop(getattr(self.session, "reload", None) or self.session.poll_file)
        self._send_controls()
        client.answer({"type": "done", "action": "reload",
                       "message": "reloaded" if result else "the file is unchanged on disk"})

    async def _on_preset(self, client, message):
        """A preset of the marble library applied to the marbles a group's keys set
        (``prefix``: ``marble``, ``stone.diffuse``, …): the rows the preset states, and the
        table's defaults for the others — what ``marble { preset "NAME" }`` means."""
        edits = preset_edits(message["prefix"], message["name"], set(self._kinds))
        version = self.session.edits(edits)
        self._refresh_controls(0.0)
        client.answer({"type": "done", "action": "preset", "version": version,
                       "message": f"{message['prefix']}: preset {message['name']}"})

    async def _on_ping(self, client, message):
        client.answer({"type": "pong", "seq": message.get("seq")})

    def _user_path(self, text: str) -> Path:
        """A path the user typed: ``~`` expanded, a relative one taken from the scene
        file's folder — or, for a packaged scene (opened by name), from the folder the
        command was started in: the package's folder is not the user's to write in."""
        path = Path(text).expanduser()
        if not path.is_absolute():
            state = self.session.state()
            scene = state.get("path")
            folder = Path(scene).parent if scene and not state.get("packaged") else Path.cwd()
            path = folder / path
        return path


#: Headers of every page and file: no caching of the token-bearing page, no sniffing,
#: the page's own CSP, and no referrer (the token must not leak in one).
_HEADERS = {"Cache-Control": "no-store", "X-Content-Type-Options": "nosniff",
            "Content-Security-Policy": CSP, "Referrer-Policy": "no-referrer"}


def preset_list() -> list:
    """The marble library's presets for the page's picker: name, title, one line."""
    from mimarble.presets import presets
    return [{"name": p.name, "title": p.title, "about": p.about} for p in presets().values()]


def preset_edits(prefix: str, name: str, keys) -> dict:
    """The edits that make the marbles under ``prefix`` preset ``name``: each row a preset
    may set (``PRESET_ROWS``) whose key ``PREFIX.ROW`` the scene has, with the preset's
    value as the library writes it, else the parameter table's default. A prefix with no
    such key, or an unknown preset: ValueError (the library's sentence)."""
    from mimarble.parameters import BY_NAME
    from mimarble.presets import PRESET_ROWS, preset
    chosen = preset(name)
    edits = {}
    for row in PRESET_ROWS:
        key = f"{prefix}.{row}"
        value = chosen.written.get(row, BY_NAME[row].default)
        if key in keys and value is not None:
            edits[key] = value
    if not edits:
        raise ValueError(f"{prefix!r:.60} names no marble of this scene")
    return edits


def compare_message(result: dict) -> bytes:
    """A compare result as a binary message: its figures as the header, the difference
    image as the body (the reference image is not sent: the page shows the difference)."""
    header = {k: v for k, v in result.items() if not isinstance(v, (bytes, bytearray))}
    header["type"] = "compare"
    header["mime"] = "image/png"
    return messages.frame_message(header, bytes(result.get("difference_png") or b""))


async def _off_loop(function, *args, **kwargs):
    """Run blocking file work (save, export, …) in a worker thread: tabs stay served."""
    return await asyncio.get_running_loop().run_in_executor(
        None, lambda: function(*args, **kwargs))


def _sentence(error: BaseException) -> str:
    """An exception's message as the one sentence the page shows."""
    text = str(error).strip() or type(error).__name__
    if isinstance(error, KeyError) and len(error.args) == 1 and isinstance(error.args[0], str):
        text = error.args[0]
    return text


def _bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (IPv6 when ``host`` is one)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host.strip("[]"), port))
        sock.listen(64)
        sock.setblocking(False)
    except OSError:
        sock.close()
        raise
    return sock


def _addresses() -> set:
    """This machine's own addresses (for --host 0.0.0.0: the Host a remote browser sends)."""
    try:
        return set(socket.gethostbyname_ex(socket.gethostname())[2])
    except OSError:
        return set()


def is_loopback(host: str) -> bool:
    """Whether ``host`` is this machine only (no warning needed)."""
    return host.strip("[]") in {name.strip("[]") for name in LOOPBACK_NAMES} | {"::1"}
