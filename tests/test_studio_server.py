"""The studio's server over a real session, without a browser (issue 41: "Bad input and
security", the edit → frame path, stale frames, two tabs, stopping).

A websocket client (the ``websockets`` library the studio extra installs) plays the page;
the scene is a 64×64 copy of fig11a in a temporary folder, so that saving writes there.
The browser itself: tests/test_studio_browser.py.
"""

import contextlib
import http.client
import json
import re
import struct
import threading
import time

import pytest

pytest.importorskip("uvicorn", reason="the studio extra is not installed")

from websockets.exceptions import ConnectionClosed, InvalidStatus  # noqa: E402
from websockets.sync.client import connect  # noqa: E402

from mimarble.runtime import packaged_scenes  # noqa: E402
from mimarble.studio import StudioSession  # noqa: E402
from mimarble.studio import messages  # noqa: E402
from mimarble.studio.server import StudioServer, _Mailbox  # noqa: E402


def small_scene(folder):
    """fig11a at 64×64 and 1 spp, in ``folder``."""
    text = packaged_scenes.find("fig11a").read_text()
    text = text.replace("width 500 height 500 samples 4", "width 64 height 64 samples 1")
    path = folder / "small.scene"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    path = small_scene(tmp_path_factory.mktemp("studio"))
    session = StudioSession(path)
    server = StudioServer(session).start()
    yield server
    server.stop()
    session.close()


def ws_url(server, token=None):
    return f"ws://127.0.0.1:{server.port}/ws?token={server.token if token is None else token}"


def own_origin(server):
    return f"http://127.0.0.1:{server.port}"


class Tab:
    """A websocket client that reads messages on a thread, as a page does."""

    def __init__(self, server):
        self._connection = connect(ws_url(server), origin=own_origin(server), max_size=None)
        self.socket = self._connection.__enter__()
        self.messages = []
        self.frames = []
        self.closed = None
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self):
        try:
            while True:
                data = self.socket.recv()
                if isinstance(data, bytes):
                    (length,) = struct.unpack(">I", data[:4])
                    header = json.loads(data[4:4 + length])
                    (self.frames if header["type"] == "frame" else self.messages).append(
                        dict(header, image_bytes=len(data) - 4 - length))
                else:
                    self.messages.append(json.loads(data))
        except ConnectionClosed as e:
            self.closed = e

    def send(self, message):
        self.socket.send(message if isinstance(message, (str, bytes)) else json.dumps(message))

    def wait(self, test, timeout=60.0, what="a message"):
        deadline = time.time() + timeout
        while time.time() < deadline:
            for m in list(self.messages):
                if test(m):
                    return m
            time.sleep(0.01)
        raise AssertionError(f"no {what} within {timeout} s; got {self.messages[-5:]}")

    def wait_frame(self, version, timeout=120.0):
        deadline = time.time() + timeout
        while time.time() < deadline:
            for f in list(self.frames):
                if f["version"] >= version:
                    return f
            time.sleep(0.01)
        raise AssertionError(f"no frame of version {version} within {timeout} s")

    def close(self):
        self._connection.__exit__(None, None, None)
        self._thread.join(5)


@contextlib.contextmanager
def fresh_studio(folder):
    """A studio of its own on a small scene in ``folder`` (for tests that write its file):
    (the scene's path, the session, the server, a tab that has had its hello)."""
    path = small_scene(folder)
    session = StudioSession(path)
    server = StudioServer(session).start()
    tab = Tab(server)
    try:
        hello = tab.wait(lambda m: m["type"] == "hello")
        yield path, session, server, tab, hello
    finally:
        tab.close()
        server.stop()
        session.close()


def get(server, path, host=None, origin=None):
    connection = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    headers = {}
    if host is not None:
        headers["Host"] = host
    if origin is not None:
        headers["Origin"] = origin
    connection.request("GET", path, headers=headers)
    response = connection.getresponse()
    return response.status, response.read().decode()


# ---- the gate -------------------------------------------------------------------------


def test_the_page_and_its_files_need_the_token(studio):
    token = studio.token
    status, page = get(studio, f"/?token={token}")
    assert status == 200 and "<title>mimarble studio</title>" in page
    assert f'content="{token}"' in page                   # the page's script reads it
    assert get(studio, f"/static/studio.js?token={token}")[0] == 200
    for path in ("/", "/?token=wrong", "/static/studio.js", "/static/studio.css?token="):
        status, body = get(studio, path)
        assert status == 403 and "token" in body and body.count("\n") == 1


def test_a_request_for_another_host_or_from_another_origin_is_refused(studio):
    token = studio.token
    status, body = get(studio, f"/?token={token}", host="rebound.example:80")
    assert status == 403 and "Host" in body
    status, body = get(studio, f"/?token={token}", origin="http://evil.example")
    assert status == 403 and "Origin" in body
    assert get(studio, f"/?token={token}", host=f"localhost:{studio.port}")[0] == 200


def test_no_request_reads_a_file_it_names(studio):
    token = studio.token
    for name in ("server.py", "..%2Fserver.py", "index.html", "%2Fetc%2Fpasswd"):
        assert get(studio, f"/static/{name}?token={token}")[0] == 404
    assert get(studio, f"/static/../server.py?token={token}")[0] in (403, 404)


def test_a_websocket_needs_the_token_and_the_servers_own_origin(studio):
    with pytest.raises(InvalidStatus) as refused:
        connect(ws_url(studio, token="nope"), origin=own_origin(studio))
    assert refused.value.response.status_code == 403
    with pytest.raises(InvalidStatus):
        connect(ws_url(studio), origin="http://evil.example")
    with pytest.raises(InvalidStatus):
        connect(ws_url(studio), origin=f"http://127.0.0.1:{studio.port + 1}")


# ---- messages ---------------------------------------------------------------------------


def test_hello_holds_the_controls_and_the_state_then_a_frame_comes(studio):
    tab = Tab(studio)
    try:
        hello = tab.wait(lambda m: m["type"] == "hello", what="hello")
        keys = {c["key"] for g in hello["controls"]["groups"] for c in g["controls"]}
        assert any(k.endswith(".period") for k in keys)
        assert hello["state"]["path"].endswith("small.scene")
        frame = tab.wait_frame(0)
        assert frame["width"] == 64 and frame["image_bytes"] > 0
    finally:
        tab.close()


def test_an_edit_is_answered_and_its_frame_follows(studio):
    tab = Tab(studio)
    try:
        tab.send({"type": "edit", "key": "marble.period", "value": 1.7, "seq": 1})
        edited = tab.wait(lambda m: m["type"] == "edited" and m["seq"] == 1, what="edited")
        frame = tab.wait_frame(edited["version"])
        assert frame["version"] >= edited["version"]
    finally:
        tab.close()


def test_a_value_out_of_range_gets_the_tables_sentence_and_changes_nothing(studio):
    tab = Tab(studio)
    try:
        before = studio.session.state()["version"]
        tab.send({"type": "edit", "key": "marble.scale", "value": -1, "seq": 7})
        invalid = tab.wait(lambda m: m["type"] == "invalid", what="invalid")
        assert invalid["seq"] == 7 and invalid["key"] == "marble.scale"
        assert "scale" in invalid["message"] and "\n" not in invalid["message"]
        tab.send({"type": "edit", "key": "marble.nosuch", "value": 1, "seq": 8})
        unknown = tab.wait(lambda m: m["type"] == "invalid" and m["seq"] == 8)
        assert "nosuch" in unknown["message"]
        assert studio.session.state()["version"] == before
    finally:
        tab.close()


@pytest.mark.parametrize("message, words", [
    ("not json at all", "not JSON"),
    ('{"type": "rm -rf"}', "unknown message type"),
    ('{"type": "edit", "key": 3, "value": 1}', "must be a string"),
    # the limits are the camera's (ZOOM_LIMITS), declared once: the server had its own
    ('{"type": "zoom", "factor": 0}', "factor must be a number in 0.001..1000"),
    (json.dumps({"type": "edit", "key": "k", "value": "x" * (messages.MAX_MESSAGE_BYTES + 1)}),
     "over the studio's limit"),
])
def test_malformed_messages_are_answered_and_the_server_goes_on(studio, message, words):
    tab = Tab(studio)
    try:
        tab.send(message)
        problem = tab.wait(lambda m: m["type"] == "problem", what="problem")
        assert words in problem["message"]
        tab.send({"type": "ping", "seq": 5})
        tab.wait(lambda m: m["type"] == "pong" and m["seq"] == 5, what="pong")
    finally:
        tab.close()


def test_a_huge_message_closes_only_its_own_socket(studio):
    tab = Tab(studio)
    tab.send("x" * (messages.MAX_WIRE_BYTES + 10))
    deadline = time.time() + 30
    while tab.closed is None and time.time() < deadline:
        time.sleep(0.05)
    assert tab.closed is not None and tab.closed.rcvd.code == 1009     # message too big
    other = Tab(studio)                                                 # still serving
    try:
        other.wait(lambda m: m["type"] == "hello", what="hello")
    finally:
        other.close()


def test_two_tabs_the_last_edit_wins_and_both_show_it(studio):
    a, b = Tab(studio), Tab(studio)
    try:
        for tab in (a, b):
            tab.wait(lambda m: m["type"] == "hello")
        a.send({"type": "edit", "key": "marble.distortion", "value": 2.5, "seq": 1})
        b.send({"type": "edit", "key": "marble.distortion", "value": 3.5, "seq": 1})
        version = b.wait(lambda m: m["type"] == "edited")["version"]

        def shows(value):
            def test(m):
                if m["type"] == "value":
                    return m["key"] == "marble.distortion" and m["value"] == value
                if m["type"] == "controls":
                    return any(c["key"] == "marble.distortion" and c["value"] == value
                               for g in m["controls"]["groups"] for c in g["controls"])
                return False
            return test
        a.wait(shows(3.5), what="tab b's edit in tab a")
        for tab in (a, b):
            assert tab.wait_frame(version)["version"] >= version
        distortions = {c["value"] for g in studio.session.controls()["groups"]
                       for c in g["controls"] if c["key"] == "marble.distortion"}
        assert distortions == {3.5}
    finally:
        a.close()
        b.close()


def test_a_tab_closed_mid_render_leaves_the_server_serving(studio):
    tab = Tab(studio)
    tab.send({"type": "edit", "key": "marble.period", "value": 2.1})
    tab.socket.close()                     # gone before its frame is rendered
    other = Tab(studio)
    try:
        other.send({"type": "edit", "key": "marble.period", "value": 2.2, "seq": 2})
        version = other.wait(lambda m: m["type"] == "edited")["version"]
        other.wait_frame(version)
        assert len(studio.clients) >= 1
    finally:
        other.close()


# ---- the mailbox: a slow tab gets the newest frame, not a queue ---------------------------


def test_a_slow_tab_gets_only_the_newest_frame():
    import asyncio

    class SlowSocket:
        def __init__(self):
            self.sent = []

        async def send_bytes(self, data):
            self.sent.append(data)
            await asyncio.sleep(0.05)                  # a slow reader

        async def send_text(self, text):
            self.sent.append(text)

    async def run():
        socket = SlowSocket()
        box = _Mailbox(socket)
        pump = asyncio.ensure_future(box.pump())
        for i in range(20):                            # 20 frames while it sends the first
            box.put("frame", b"frame %d" % i)
            await asyncio.sleep(0.001)
        box.answer({"type": "edited", "seq": 1})
        await asyncio.sleep(0.3)
        pump.cancel()
        return socket.sent

    sent = asyncio.run(run())
    frames = [s for s in sent if isinstance(s, bytes)]
    assert frames[0] == b"frame 0" and frames[-1] == b"frame 19"
    assert len(frames) <= 3                            # the stale ones were dropped
    assert any(isinstance(s, str) and '"edited"' in s for s in sent)


def test_a_tab_that_sends_without_reading_is_held_to_a_bounded_queue(studio):
    """A tab that sends pings as fast as it can and reads nothing (its socket's sends
    block): the server stops reading its messages once MAX_ANSWERS answers wait, instead
    of holding an answer for every message; when the tab reads, every ping is answered."""
    import asyncio
    from mimarble.studio.server import MAX_ANSWERS

    class Flooding:
        """The server's side of a websocket whose peer floods and does not read."""
        def __init__(self):
            self.received, self.sent = 0, []
            self.reading = asyncio.Event()          # set: the peer reads again
            self.done = False

        async def accept(self):
            pass

        async def receive(self):
            if self.done:
                return {"type": "websocket.disconnect"}
            self.received += 1
            await asyncio.sleep(0)
            return {"type": "websocket.receive",
                    "text": json.dumps({"type": "ping", "seq": self.received})}

        async def send_text(self, text):
            await self.reading.wait()
            self.sent.append(json.loads(text))

        async def send_bytes(self, data):
            await self.reading.wait()

    async def run():
        socket = Flooding()
        serving = asyncio.ensure_future(studio._websocket(socket))
        await asyncio.sleep(0.5)
        received_while_blocked = socket.received
        socket.reading.set()
        for _ in range(200):
            await asyncio.sleep(0.005)
        socket.done = True
        await asyncio.wait_for(serving, 10)
        return socket, received_while_blocked

    socket, received_while_blocked = asyncio.run(run())
    assert received_while_blocked <= MAX_ANSWERS + 1
    pongs = [m["seq"] for m in socket.sent if m["type"] == "pong"]
    assert socket.received > 2 * MAX_ANSWERS          # read again once the tab read
    assert pongs == list(range(1, len(pongs) + 1)) and len(pongs) >= socket.received - 1


def test_a_tab_gone_while_its_answers_are_full_ends_its_connection(studio):
    """A tab that floods, reads nothing, then goes away: the server's send fails while
    MAX_ANSWERS answers wait. The connection's handler ends (it does not wait for room
    that no send will make) and the tab leaves the server's clients."""
    import asyncio

    class Gone:
        """The server's side of a websocket whose peer flooded and closed."""
        def __init__(self):
            self.received = 0

        async def accept(self):
            pass

        async def receive(self):
            self.received += 1
            await asyncio.sleep(0)
            return {"type": "websocket.receive",
                    "text": json.dumps({"type": "ping", "seq": self.received})}

        async def send_text(self, text):
            await asyncio.sleep(0.05)
            raise ConnectionResetError("the peer is gone")

        async def send_bytes(self, data):
            await self.send_text(None)

    async def run():
        serving = asyncio.ensure_future(studio._websocket(Gone()))
        try:
            await asyncio.wait_for(asyncio.shield(serving), 5)
            return True
        except asyncio.TimeoutError:
            serving.cancel()
            return False

    clients = len(studio.clients)
    assert asyncio.run(run()), "the handler of a gone tab never ended"
    assert len(studio.clients) == clients


# ---- stopping ------------------------------------------------------------------------------


def test_stopping_leaves_no_thread(tmp_path):
    before = set(threading.enumerate())
    session = StudioSession(small_scene(tmp_path))
    server = StudioServer(session).start()
    tab = Tab(server)
    tab.wait(lambda m: m["type"] == "hello")
    server.stop()
    session.close()
    tab.close()
    def left():
        return [t.name for t in set(threading.enumerate()) - before
                if re.match("mimarble-studio", t.name)]
    deadline = time.time() + 10
    while time.time() < deadline and left():
        time.sleep(0.05)
    assert left() == []
    with pytest.raises(OSError):
        http.client.HTTPConnection("127.0.0.1", server.port, timeout=5).request("GET", "/")


# ---- the buttons: snapshot, export, save as, compare ----------------------------------------


def test_snapshot_export_and_save_as_write_the_files_the_user_names(studio, tmp_path):
    tab = Tab(studio)
    try:
        tab.wait(lambda m: m["type"] == "hello")
        for kind, path, extra in (("snapshot", tmp_path / "shot.png", {}),
                                  ("export", tmp_path / "scene.xml", {}),
                                  ("export", tmp_path / "scene.py", {"python": True})):
            tab.send({"type": kind, "path": str(path), **extra})
            done = tab.wait(lambda m: m["type"] == "done" and str(path) in m["message"],
                            what=f"{kind} done")
            assert done["action"] == kind and path.stat().st_size > 0
        assert (tmp_path / "shot.png").read_bytes()[:4] == b"\x89PNG"
        assert "<scene" in (tmp_path / "scene.xml").read_text()
        tab.send({"type": "snapshot", "path": str(tmp_path / "no-such-folder" / "x.png")})
        problem = tab.wait(lambda m: m["type"] == "problem" and m["action"] == "snapshot")
        assert "\n" not in problem["message"]
        assert not (tmp_path / "no-such-folder").exists()
    finally:
        tab.close()


def test_save_as_writes_a_copy_relative_to_the_scene_and_the_session_follows_it(tmp_path):
    with fresh_studio(tmp_path) as (path, session, server, tab, _):
        tab.send({"type": "edit", "key": "marble.distortion", "value": 2.25, "seq": 1})
        tab.wait(lambda m: m["type"] == "edited")
        tab.send({"type": "save_as", "path": "copy.scene"})
        tab.wait(lambda m: m["type"] == "done" and m["action"] == "save_as", what="saved as")
        copy = tmp_path / "copy.scene"
        assert "distortion 2.25" in copy.read_text()
        assert "distortion 2.25" not in path.read_text()
        assert session.state()["path"] == str(copy)


def test_compare_shows_the_difference_and_psnr(studio):
    tab = Tab(studio)
    try:
        tab.wait(lambda m: m["type"] == "hello")
        tab.send({"type": "compare"})
        tab.wait(lambda m: m["type"] == "done" and m["action"] == "compare")
        result = tab.wait(lambda m: m["type"] == "compare", timeout=300, what="the compare")
        assert result["status"] == "done", result
        assert result["psnr"] > 100                 # whitted against the float64 reference
        assert result["image_bytes"] > 0            # the difference image came with it
    finally:
        tab.close()


def test_a_preset_picked_sets_the_groups_marbles_as_the_scene_language_would(tmp_path):
    from mimarble import scene as scene_language
    with fresh_studio(tmp_path) as (path, session, server, tab, hello):
        assert "carrara" in {p["name"] for p in hello["presets"]}
        tab.send({"type": "preset", "prefix": "marble", "name": "carrara"})
        tab.wait(lambda m: m["type"] == "done" and m["action"] == "preset", what="preset")
        # the same marble written with the scene language's preset
        text = path.read_text()
        start = text.index("marble {", text.index("diffuse {"))
        end = text.index("}", text.index("ramp {", start)) + 1
        expected = scene_language.parse(text[:start] + 'marble { preset "carrara" ' +
                                        text[end:], filename=str(path))
        got = session.scene.materials["marble"].diffuse
        assert got == expected.materials["marble"].diffuse
        tab.send({"type": "preset", "prefix": "marble", "name": "carara"})
        problem = tab.wait(lambda m: m["type"] == "problem" and m["action"] == "preset")
        assert "carrara" in problem["message"]                  # the closest name


def test_save_refuses_a_file_changed_on_disk_and_reload_takes_the_files(tmp_path):
    with fresh_studio(tmp_path) as (path, session, server, tab, _):
        tab.send({"type": "edit", "key": "marble.distortion", "value": 2.25, "seq": 1})
        tab.wait(lambda m: m["type"] == "edited")
        theirs = path.read_text().replace("period 1.3", "period 1.9")
        path.write_text(theirs)                       # an editor saved meanwhile
        tab.wait(lambda m: m["type"] == "state" and m["state"]["disk_changed"],
                 what="disk_changed")
        tab.send({"type": "save"})
        problem = tab.wait(lambda m: m["type"] == "problem" and m["action"] == "save")
        assert "changed on disk" in problem["message"]
        assert path.read_text() == theirs             # nothing written
        tab.send({"type": "reload"})
        tab.wait(lambda m: m["type"] == "done" and m["action"] == "reload")
        assert session.edits_made == {} and session.text == theirs


@pytest.mark.parametrize("packaged", [False, True])
def test_a_relative_name_is_from_the_scenes_folder_or_for_a_packaged_scene_the_working_one(
        tmp_path, monkeypatch, packaged):
    """Save as, Snapshot and Export: a packaged scene's folder (the installed package, or the
    checkout's scenes/) is not where a user's files go."""
    class Session:                       # what the server reads of the session here
        def state(self):
            return {"path": str(tmp_path / "scenes" / "a.scene"), "packaged": packaged}

    monkeypatch.chdir(tmp_path)
    server = StudioServer(Session())
    try:
        chosen = server._user_path("shot.png")
    finally:
        server._socket.close()
    assert chosen == (tmp_path if packaged else tmp_path / "scenes") / "shot.png"
