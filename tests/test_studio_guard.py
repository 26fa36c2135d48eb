"""The studio server's gate and its messages, without a renderer (issue 41, "Bad input and
security"): the token, Host and Origin checks of mimarble/studio/guard.py on a bare ASGI
app, and the checks mimarble/studio/messages.py makes of every message a page sends.

The same rules through the real server and session: tests/test_studio_server.py.
"""

import asyncio
import json
import struct

import pytest

from mimarble.studio import messages
from mimarble.studio.guard import Guard, host_names, new_token


def test_tokens_are_random_and_long():
    tokens = {new_token() for _ in range(100)}
    assert len(tokens) == 100
    assert all(len(t) >= 43 for t in tokens)


def test_host_names_are_the_loopback_names_and_the_bound_host_with_the_port():
    names = host_names("127.0.0.1", 8123)
    assert names == {"127.0.0.1:8123", "localhost:8123", "[::1]:8123"}
    assert "myhost:8123" in host_names("myhost", 8123)
    assert "[fe80::1]:9" in host_names("fe80::1", 9)
    assert host_names("0.0.0.0", 5) == host_names("127.0.0.1", 5)


class _Recorder:
    """A bare ASGI app that records whether a request reached it."""

    def __init__(self):
        self.reached = []

    async def __call__(self, scope, receive, send):
        self.reached.append(scope["type"])
        if scope["type"] == "http":
            await send({"type": "http.response.start", "status": 200, "headers": []})
            await send({"type": "http.response.body", "body": b"ok"})


def _call(guard, kind="http", host="127.0.0.1:8000", origin=None, query=b""):
    headers = [(b"host", host.encode())] if host is not None else []
    if origin is not None:
        headers.append((b"origin", origin.encode()))
    scope = {"type": kind, "headers": headers, "query_string": query, "path": "/"}
    sent = []

    async def receive():
        return {"type": "http.request", "body": b""}

    async def send(message):
        sent.append(message)

    asyncio.run(guard(scope, receive, send))
    return sent


@pytest.fixture
def gate():
    app = _Recorder()
    token = new_token()
    return app, token, Guard(app, token, host_names("127.0.0.1", 8000))


def test_a_request_with_the_token_and_its_own_host_passes(gate):
    app, token, guard = gate
    sent = _call(guard, query=f"token={token}".encode())
    assert app.reached == ["http"] and sent[0]["status"] == 200
    _call(guard, host="localhost:8000", origin="http://localhost:8000",
          query=f"x=1&token={token}".encode())
    assert app.reached == ["http", "http"]


@pytest.mark.parametrize("case", ["no token", "wrong token", "prefix of the token",
                                  "other host", "other port", "no host", "other origin",
                                  "origin on another port", "null origin"])
def test_requests_without_the_token_or_from_elsewhere_are_refused(gate, case):
    app, token, guard = gate
    query = f"token={token}".encode()
    kwargs = {"no token": dict(query=b""),
              "wrong token": dict(query=b"token=" + new_token().encode()),
              "prefix of the token": dict(query=f"token={token[:-1]}".encode()),
              "other host": dict(host="evil.example:8000", query=query),
              "other port": dict(host="127.0.0.1:8001", query=query),
              "no host": dict(host=None, query=query),
              "other origin": dict(origin="http://evil.example", query=query),
              "origin on another port": dict(origin="http://127.0.0.1:9999", query=query),
              "null origin": dict(origin="null", query=query)}[case]
    sent = _call(guard, **kwargs)
    assert app.reached == []
    assert sent[0]["status"] == 403
    body = sent[1]["body"].decode()
    assert body.count("\n") == 1 and len(body) < 200      # one sentence


def test_a_refused_websocket_is_closed_before_it_is_accepted(gate):
    app, token, guard = gate
    sent = _call(guard, kind="websocket", origin="http://evil.example",
                 query=f"token={token}".encode())
    assert app.reached == [] and sent == [sent[0]]
    assert sent[0]["type"] == "websocket.close" and sent[0]["code"] == 1008
    sent = _call(guard, kind="websocket", origin="http://127.0.0.1:8000", query=b"")
    assert app.reached == [] and sent[0]["type"] == "websocket.close"
    _call(guard, kind="websocket", origin="http://127.0.0.1:8000",
          query=f"token={token}".encode())
    assert app.reached == ["websocket"]


# ---- messages -----------------------------------------------------------------------


def test_well_formed_messages_are_returned_as_dicts():
    m = messages.parse('{"type": "edit", "key": "marble.period", "value": 1.5, "seq": 3}')
    assert m == {"type": "edit", "key": "marble.period", "value": 1.5, "seq": 3}
    assert messages.parse(b'{"type": "save"}') == {"type": "save"}
    assert messages.parse('{"type": "export", "path": "a.xml"}')["path"] == "a.xml"
    # an edit's value is any JSON value: the parameter table judges it, not the transport
    assert messages.parse('{"type":"edit","key":"k","value":["#ffffff","#000000"]}')["value"]


@pytest.mark.parametrize("text, words", [
    ("not json", "not JSON"),
    ("[1, 2]", "JSON object"),
    ('"edit"', "JSON object"),
    ("{}", "unknown message type"),
    ('{"type": "format_disk"}', "unknown message type 'format_disk'"),
    ('{"type": "edit", "value": 1}', "needs the field 'key'"),
    ('{"type": "edit", "key": 5, "value": 1}', "'key' must be a string"),
    ('{"type": "edit", "key": "k", "value": 1, "extra": 2}', "has no field 'extra'"),
    ('{"type": "orbit", "dx": "1", "dy": 0}', "'dx' must be a number"),
    ('{"type": "orbit", "dx": true, "dy": 0}', "'dx' must be a number"),
    ('{"type": "zoom", "factor": NaN}', "not a number JSON allows"),
    ('{"type": "zoom", "factor": 1e999}', "finite"),
    ('{"type": "zoom", "factor": 1' + "0" * 400 + '}', "finite"),
    ('{"type": "edit", "key": "k", "value": [-1' + "0" * 400 + ']}', "finite"),
    ('{"type": "save_as", "path": "' + "a" * 5000 + '"}', "at most 4096"),
    ('{"type": "edit", "key": "k", "value": [[[[[[1]]]]]]}', "nested too deeply"),
])
def test_bad_messages_are_one_sentence(text, words):
    with pytest.raises(messages.MessageError) as caught:
        messages.parse(text)
    assert words in str(caught.value)
    assert "\n" not in str(caught.value)


def test_a_message_over_the_limit_is_refused_before_it_is_read():
    big = json.dumps({"type": "edit", "key": "k", "value": "x" * messages.MAX_MESSAGE_BYTES})
    with pytest.raises(messages.MessageError, match="over the studio's limit"):
        messages.parse(big)


def test_a_frame_message_carries_its_header_and_image():
    data = messages.frame_message({"type": "frame", "version": 7}, b"\x89PNG...")
    (length,) = struct.unpack(">I", data[:4])
    assert json.loads(data[4:4 + length]) == {"type": "frame", "version": 7}
    assert data[4 + length:] == b"\x89PNG..."


def test_the_page_and_the_server_name_no_parameter():
    """Controls come from the engine's controls() (the parameter table): no parameter's name
    is written in the page's files or the server as a string of its own."""
    from pathlib import Path

    from mimarble.parameters import PARAMETERS
    folder = Path(messages.__file__).parent
    texts = {path.name: path.read_text() for path in
             [folder / "server.py", folder / "messages.py", *(folder / "static").iterdir()]}
    assert {"studio.js", "index.html", "studio.css", "server.py"} <= set(texts)
    for parameter in PARAMETERS:
        for quoted in (f'"{parameter.name}"', f"'{parameter.name}'", f"`{parameter.name}`",
                       f'"marble.{parameter.name}"'):
            found = [name for name, text in texts.items() if quoted in text]
            assert found == [], f"{quoted} written in {found}"
