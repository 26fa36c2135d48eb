"""``mimarble studio`` (issue 41 item 1) and ``mimarble.studio(scene)`` in a notebook (item 7):
the URL with its token printed, the page served, Ctrl-C → one line and exit status 0 with
nothing left running; bad arguments and a bad scene answered in one sentence (exit 2);
the missing extra named.
"""

import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import pytest

pytest.importorskip("uvicorn", reason="the studio extra is not installed")

from mimarble.runtime import extras, packaged_scenes  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: Straight to the server: an http_proxy in the environment must not carry these requests.
OPENER = urllib.request.build_opener(urllib.request.ProxyHandler({}))


def small_scene(folder):
    text = packaged_scenes.find("fig11a").read_text()
    path = folder / "small.scene"
    path.write_text(text.replace("width 500 height 500 samples 4", "width 32 height 32 samples 1"))
    return path


def start(*args):
    env = dict(os.environ, PYTHONPATH=ROOT, PYTHONUNBUFFERED="1")
    env.pop("DISPLAY", None)
    return subprocess.Popen([sys.executable, "-m", "mimarble", "studio", *map(str, args)],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def read_url(process, timeout=240.0):
    deadline = time.time() + timeout
    lines = []
    while time.time() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        lines.append(line)
        found = re.search(r"http://\S+\?token=\S+", line)
        if found:
            return found.group(0), lines
    process.kill()
    raise AssertionError(f"no URL printed: {lines} {process.stderr.read()}")


def test_the_command_prints_its_url_serves_the_page_and_stops_on_ctrl_c(tmp_path):
    process = start(small_scene(tmp_path), "--no-browser")
    try:
        url, _ = read_url(process)
        assert url.startswith("http://127.0.0.1:")
        token = url.split("token=")[1]
        assert len(token) >= 43
        with OPENER.open(url, timeout=30) as response:
            assert response.status == 200 and b"mimarble studio" in response.read()
        with pytest.raises(urllib.error.HTTPError) as refused:
            OPENER.open(url.split("?")[0], timeout=30)
        assert refused.value.code == 403
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err
    assert err.strip().splitlines() == ["mimarble: studio stopped"]
    port = int(url.split(":")[2].split("/")[0])
    with socket.socket() as probe:                     # nothing listens any more
        assert probe.connect_ex(("127.0.0.1", port)) != 0


def test_another_host_is_warned_about(tmp_path):
    process = start(small_scene(tmp_path), "--no-browser", "--host", "0.0.0.0")
    try:
        read_url(process)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert "mimarble: warning: --host 0.0.0.0: the studio is reachable from other machines" in err
    assert process.returncode == 0


def test_a_bad_scene_and_a_taken_port_are_one_sentence(tmp_path):
    bad = tmp_path / "bad.scene"
    bad.write_text("camera {\n  foo\n")
    result = subprocess.run([sys.executable, "-m", "mimarble", "studio", str(bad), "--no-browser"],
                            cwd=ROOT, capture_output=True, text=True, timeout=120,
                            env=dict(os.environ, PYTHONPATH=ROOT))
    assert result.returncode == 2 and result.stderr.startswith(f"{bad}:2:3:")
    assert "Traceback" not in result.stderr
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        result = subprocess.run([sys.executable, "-m", "mimarble", "studio",
                                 str(small_scene(tmp_path)), "--no-browser", "--port", str(port)],
                                cwd=ROOT, capture_output=True, text=True, timeout=240,
                                env=dict(os.environ, PYTHONPATH=ROOT))
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"mimarble: cannot listen on 127.0.0.1:{port}: Address already in use"]
    result = subprocess.run([sys.executable, "-m", "mimarble", "studio", str(bad.with_name(
                             "small.scene")), "--mode", "preview", "--no-browser"], cwd=ROOT,
                            capture_output=True, text=True, timeout=240,
                            env=dict(os.environ, PYTHONPATH=ROOT))
    assert result.returncode == 2 and result.stderr.strip().splitlines() == [
        "mimarble: --mode preview: mode 'preview' is not one of whitted, path"]
    result = subprocess.run([sys.executable, "-m", "mimarble", "studio", "x.scene", "--port",
                             "70000"], cwd=ROOT, capture_output=True, text=True, timeout=60,
                            env=dict(os.environ, PYTHONPATH=ROOT))
    assert result.returncode == 2 and "a port lies in 0..65535" in result.stderr


def test_without_the_extra_the_studio_says_how_to_install_it(monkeypatch):
    real = extras.importlib.import_module

    def without_uvicorn(name, *args):
        if name == "uvicorn":
            raise ImportError("No module named 'uvicorn'")
        return real(name, *args)
    monkeypatch.setattr(extras.importlib, "import_module", without_uvicorn)
    sentence = extras.missing_extra("studio")
    assert sentence == ("the marble studio's pages (mimarble studio, mimarble.studio) need "
                        "the 'studio' extra: pip install 'mimarble[studio]'")
    import mimarble
    with pytest.raises(extras.MissingExtra, match=r"pip install 'mimarble\[studio\]'"):
        mimarble.studio("fig11a")


def test_the_notebooks_studio_is_an_iframe_of_the_same_page(tmp_path):
    import mimarble
    view = mimarble.studio(small_scene(tmp_path))
    try:
        html = view._repr_html_()
        assert html.startswith("<iframe") and view.url.replace("&", "&amp;") in html
        with OPENER.open(view.url, timeout=30) as response:
            assert b'src="/static/studio.js' in response.read()
    finally:
        view.close()
    assert "closed" in view._repr_html_()


def test_a_packaged_scene_opened_by_name_is_not_saved_over(monkeypatch):
    """``mimarble.studio("fig11a")`` and ``mimarble studio fig11a``: the packaged file is
    the package's (or the checkout's scenes/), so Save refuses it. The callers resolved the
    name before the session saw it, and the session took it for a user's file."""
    import mimarble
    from mimarble.studio import StudioError
    packaged = packaged_scenes.find("fig11a")
    before = packaged.read_bytes()
    view = mimarble.studio("fig11a")
    try:
        assert view.session.state()["packaged"]
        view.session.edit("marble.period", 2.0)
        with pytest.raises(StudioError, match="packaged scene"):
            view.session.save()
    finally:
        view.close()
        if packaged.read_bytes() != before:             # never leave the checkout changed
            packaged.write_bytes(before)
    assert packaged.read_bytes() == before


def test_the_command_does_not_save_over_a_packaged_scene_named():
    from websockets.sync.client import connect
    import json
    packaged = packaged_scenes.find("fig11a")
    before = packaged.read_bytes()
    process = start("fig11a", "--no-browser")
    try:
        url, _ = read_url(process)
        port, token = url.split(":")[2].split("/")[0], url.split("token=")[1]
        with connect(f"ws://127.0.0.1:{port}/ws?token={token}",
                     origin=f"http://127.0.0.1:{port}", max_size=None) as socket_:
            socket_.send(json.dumps({"type": "edit", "key": "marble.period", "value": 2.0}))
            socket_.send(json.dumps({"type": "save"}))
            deadline = time.time() + 120
            while time.time() < deadline:
                data = socket_.recv(timeout=120)
                if isinstance(data, str) and json.loads(data).get("action") == "save":
                    answer = json.loads(data)
                    break
        assert answer["type"] == "problem" and "packaged scene" in answer["message"]
        process.send_signal(signal.SIGINT)
        process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
        if packaged.read_bytes() != before:             # never leave the checkout changed
            packaged.write_bytes(before)
    assert packaged.read_bytes() == before
