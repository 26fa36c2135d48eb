"""The marble studio's latency, measured in a real (headless) browser (issue 41's targets).

    ./go python scripts/studio_browser_latency.py [--edits N] [--drag-seconds S]
        [--panel] [--json OUT.json] [--screenshot docs/gallery/studio.png] [--no-reduced]

Opens the studio (mimarble/studio/server.py) on fig11a at 512×512 in Debian's headless
Chromium (mimarble/studio/headless.py) and measures, in the page, with
``performance.now()``:

* **edit → frame on screen**: from the period slider's ``input`` event (dispatched as the
  slider would) to the ``load`` of the image that shows that edit — ``--edits`` edits one
  after another, each waiting for its frame (median, 95th percentile);
* **dragging**: ``input`` events every 16.7 ms (a 60 Hz drag) for ``--drag-seconds``: frames
  shown per second, and the latency of each edit shown (stale ones are dropped, never shown);
* **a structural edit** (octaves 8 → 9, which records new kernels, then back to 8): the
  longest gap between the page's animation frames (a page blocked by a long task shows
  here), the time until the edit is on screen, and whether "compiling" was shown.

``--panel`` also measures the alternative considered for the server, Panel (Bokeh's
server and widgets: one app for the browser and Jupyter), over the same session: a
``FloatSlider`` whose value the page sets as a drag would, and an HTML pane showing the
frame as an ``<img>`` (as Panel's image panes do); its latency is timed from setting the
slider's model to the first animation frame after the pane's new HTML arrived.
Needs ``pip install panel`` (not a dependency of mimarble).

The targets (median ≤ 50 ms, 95th percentile ≤ 100 ms, ≥ 20 frames/s dragging, no page
frame blocked > 100 ms) are printed beside the figures; the CPU and load are printed too.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import statistics
import sys
import time
from pathlib import Path

SCENE = "fig11a"
SIZE = 512
TARGETS = {"median_ms": 50.0, "p95_ms": 100.0, "drag_fps": 20.0, "longest_gap_ms": 100.0}

# The page's helpers: drive the period slider as a user's drag does (its `input` event).
_DRIVE = """
window.__drive = (key, value) => {
  const el = document.getElementById("c-" + key.replace(/[^A-Za-z0-9_-]/g, "_"));
  if (el && el.type === "range") {
    el.value = value; el.dispatchEvent(new Event("input", {bubbles: true}));
  } else window.studio.edit(key, value);
};
"""

_ONE_BY_ONE = _DRIVE + """
const [key, values, pause, done] = arguments;
const s = window.studio, out = [];
let i = 0, lost = 0;
function next() {
  if (i >= values.length) { done({latencies: out, lost}); return; }
  const before = s.latencies.length, t0 = performance.now();
  window.__drive(key, values[i++]);
  const wait = () => {
    if (s.latencies.length > before) { out.push(s.latencies[before]); setTimeout(next, pause); }
    else if (performance.now() - t0 > 10000) { lost++; setTimeout(next, pause); }   // never shown
    else setTimeout(wait, 1);
  };
  wait();
}
next();
"""

_DRAG = _DRIVE + """
const [key, values, interval, done] = arguments;
const s = window.studio, l0 = s.latencies.length, f0 = s.frames.length;
s.resetGap();
const t0 = performance.now();
let i = 0;
const timer = setInterval(() => {
  if (i < values.length) { window.__drive(key, values[i++]); return; }
  clearInterval(timer);
  const t1 = performance.now();
  setTimeout(() => done({latencies: s.latencies.slice(l0),
                         frames: s.frames.slice(f0).filter((f) => f.t <= t1).length,
                         seconds: (t1 - t0) / 1000, longest_gap: s.longestGap}), 1500);
}, interval);
"""

_STRUCTURAL = """
const [key, value, done] = arguments;
const s = window.studio, before = s.latencies.length;
s.resetGap(); s.compilingSeen = false;
const t0 = performance.now();
s.edit(key, value);
const wait = () => {
  if (s.latencies.length > before) {
    const shown = performance.now() - t0;
    // keep watching the page's frames a little after the edit is shown
    setTimeout(() => done({shown_ms: shown, longest_gap: s.longestGap,
                           compiling_seen: s.compilingSeen}), 300);
  } else setTimeout(wait, 5);
};
wait();
"""


def percentile(values, q: float) -> float:
    """The q-th percentile (0..100), linear between order statistics."""
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    k = (len(ordered) - 1) * q / 100
    lo, hi = int(k), min(int(k) + 1, len(ordered) - 1)
    return ordered[lo] + (ordered[hi] - ordered[lo]) * (k - lo)


def summary(latencies) -> dict:
    return {"n": len(latencies), "median_ms": round(statistics.median(latencies), 1),
            "p95_ms": round(percentile(latencies, 95), 1), "max_ms": round(max(latencies), 1)}


def period_values(n: int) -> list:
    """Values a drag of the period slider passes (steps of 0.01 around fig11a's 1.3)."""
    return [round(1.3 + 0.01 * ((i % 40) if (i // 40) % 2 == 0 else 40 - i % 40), 2)
            for i in range(1, n + 1)]


def in_chunks(driver, script, values, *key, size=10, pause_ms=50) -> dict:
    """``script`` over ``values`` ten at a time (each call well within Selenium's timeout)."""
    total = {"latencies": [], "lost": 0}
    for start in range(0, len(values), size):
        part = driver.execute_async_script(script, *key, values[start:start + size], pause_ms)
        total["latencies"] += part["latencies"]
        total["lost"] += part["lost"]
    return total


def wait_final(session, timeout: float = 300.0):
    version = session.state()["version"]
    return session.wait_frame(version, final=True, timeout=timeout)


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}"


def measure_studio(driver, session, edits: int, drag_seconds: float, screenshot,
                   structural_edits: bool = True) -> dict:
    from mimarble.studio.server import StudioServer
    with StudioServer(session) as server:
        driver.get(server.url)
        driver.set_script_timeout(600)
        deadline = time.time() + 120
        while not driver.execute_script("return !!(window.studio && window.studio.frames.length)"):
            if time.time() > deadline:
                raise RuntimeError("the studio page showed no frame within 120 s")
            time.sleep(0.05)
        wait_final(session)
        time.sleep(0.5)
        one = in_chunks(driver, _ONE_BY_ONE, period_values(edits), "marble.period")
        wait_final(session)
        drag = driver.execute_async_script(_DRAG, "marble.period",
                                           period_values(int(drag_seconds * 60)), 1000 / 60)
        wait_final(session)
        structural = []
        for octaves in (8, 9, 8) if structural_edits else ():       # 12 → 8 (new), 8 → 9 (new), 9 → 8 (recorded before)
            structural.append(dict(driver.execute_async_script(
                _STRUCTURAL, "marble.octaves", octaves), octaves=octaves))
            wait_final(session)
        if screenshot:
            driver.execute_script("window.studio.edit('marble.octaves', 12);"
                                  "window.studio.edit('marble.period', 1.3);")
            wait_final(session)
            time.sleep(1.0)
            driver.save_screenshot(str(screenshot))
        return {"one_by_one": dict(summary(one["latencies"]), lost=one["lost"]),
                "latencies": [round(x, 1) for x in one["latencies"]],
                "drag": {**summary(drag["latencies"]),
                         "frames_per_s": round(drag["frames"] / drag["seconds"], 1),
                         "longest_gap_ms": round(drag["longest_gap"], 1)},
                "structural": [{"octaves": v["octaves"], "shown_ms": round(v["shown_ms"], 1),
                                "longest_gap_ms": round(v["longest_gap"], 1),
                                "compiling_seen": v["compiling_seen"]} for v in structural]}


# ---- the alternative: Panel ----------------------------------------------------------

_PANEL_FIND = """
const doc = window.Bokeh && Bokeh.documents[0];
if (!doc) return false;
const models = [...doc.all_models];
window.__slider = models.find((m) => m.title === "period" && typeof m.value === "number");
window.__pane = models.find((m) => typeof m.text === "string" && m.text.includes("data:image"));
if (!window.__slider || !window.__pane) return false;
window.__changes = [];
window.__pane.properties.text.change.connect(() => {
  const period = (/data-period=(?:"|&quot;)([^"&]*)/.exec(window.__pane.text) || [])[1];
  requestAnimationFrame(() => window.__changes.push({t: performance.now(), period}));
});
return true;
"""

_PANEL_ONE_BY_ONE = """
const [values, pause, done] = arguments;
const out = [];
let i = 0, lost = 0;
function next() {
  if (i >= values.length) { done({latencies: out, lost}); return; }
  const before = window.__changes.length, t0 = performance.now(), value = values[i++];
  window.__slider.value = value;
  const wait = () => {    // the first frame on screen that shows this value
    const shown = window.__changes.slice(before).find((c) => Number(c.period) === value);
    if (shown) { out.push(shown.t - t0); setTimeout(next, pause); }
    else if (performance.now() - t0 > 10000) { lost++; setTimeout(next, pause); }
    else setTimeout(wait, 1);
  };
  wait();
}
next();
"""

_PANEL_DRAG = """
const [values, interval, done] = arguments;
const before = window.__changes.length, t0 = performance.now();
let i = 0;
const timer = setInterval(() => {
  if (i < values.length) { window.__slider.value = values[i++]; return; }
  clearInterval(timer);
  const t1 = performance.now();
  setTimeout(() => done({frames: window.__changes.slice(before).filter((c) => c.t <= t1).length,
                         seconds: (t1 - t0) / 1000}), 1500);
}, interval);
"""


def measure_panel(driver, session, edits: int, drag_seconds: float) -> dict:
    import base64

    import panel as pn

    def app():
        slider = pn.widgets.FloatSlider(name="period", start=0.5, end=3.0, step=0.01, value=1.3)
        frame = session.latest_frame()
        pane = pn.pane.HTML(_img(frame), width=SIZE, height=SIZE)

        # A frame from the render thread reaches the document through a periodic callback
        # on the server's own loop (Panel's way for data made by another thread; a
        # next-tick callback from the render thread was not flushed until the next event).
        shown = {"frame": None}

        def show_newest():
            newest = session.latest_frame()
            if newest is not None and newest is not shown["frame"]:
                shown["frame"] = newest
                pane.object = _img(newest)

        pn.state.add_periodic_callback(show_newest, period=5)

        def on_slider(event):
            periods[session.edit("marble.period", event.new)] = event.new

        slider.param.watch(on_slider, "value")
        return pn.Row(slider, pane)

    periods = {}      # version -> the period it shows: the page finds its edit's frame by it

    def _img(frame):
        data = base64.b64encode(frame.image).decode() if frame is not None else ""
        period = periods.get(frame.version, "") if frame is not None else ""
        return (f'<img data-period="{period}" '
                f'src="data:{frame.mime if frame else "image/png"};base64,{data}">')

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = pn.serve(app, port=port, address="127.0.0.1", threaded=True, show=False,
                      websocket_origin=[f"127.0.0.1:{port}"])
    try:
        time.sleep(2.0)
        driver.get(f"http://127.0.0.1:{port}/")
        driver.set_script_timeout(600)
        deadline = time.time() + 60
        while not driver.execute_script(_PANEL_FIND):
            if time.time() > deadline:
                raise RuntimeError("Panel's page did not show its slider and image")
            time.sleep(0.1)
        wait_final(session)
        one = in_chunks(driver, _PANEL_ONE_BY_ONE, period_values(edits))
        wait_final(session)
        drag = driver.execute_async_script(_PANEL_DRAG, period_values(int(drag_seconds * 60)),
                                           1000 / 60)
        wait_final(session)
        return {"one_by_one": dict(summary(one["latencies"]), lost=one["lost"]),
                "latencies": [round(x, 1) for x in one["latencies"]],
                "drag": {"frames_per_s": round(drag["frames"] / drag["seconds"], 1)},
                "version": pn.__version__}
    finally:
        server.stop()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--edits", type=int, default=60)
    parser.add_argument("--drag-seconds", type=float, default=3.0)
    parser.add_argument("--panel", action="store_true", help="also measure Panel")
    parser.add_argument("--rounds", type=int, default=1,
                        help="measure this many times, the studio and Panel taking turns "
                             "(the machine's load drifts; turns share it alike)")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--screenshot", type=Path)
    parser.add_argument("--no-reduced", action="store_true",
                        help="whole frames only, also while the slider moves (the render "
                             "thread's reduced frames off: mimarble/studio/worker.py)")
    args = parser.parse_args(argv)

    import mimarble  # noqa: F401  (starts Dr.Jit and Mitsuba, registers the plugins)
    from mimarble.studio import StudioSession
    from mimarble.studio.headless import browser_problem, start_browser
    problem = browser_problem()
    if problem:
        print(f"studio_browser_latency: {problem}", file=sys.stderr)
        return 2
    results = {"machine": machine(), "scene": f"{SCENE} {SIZE}x{SIZE}"}
    driver = start_browser()
    try:
        with StudioSession(SCENE) as session:
            if args.no_reduced:
                session._worker.frame_budget_s = None
            strides: dict = {}

            def count(kind, payload):
                if kind == "frame":
                    strides[payload.stride] = strides.get(payload.stride, 0) + 1
            session.subscribe(count)
            session.edits({"image.width": SIZE, "image.height": SIZE})
            wait_final(session)
            for turn in range(args.rounds):
                last = turn == args.rounds - 1
                results.setdefault("studio", []).append(measure_studio(
                    driver, session, args.edits, args.drag_seconds,
                    args.screenshot if last else None, structural_edits=turn == 0))
                if args.panel:
                    results.setdefault("panel", []).append(
                        measure_panel(driver, session, args.edits, args.drag_seconds))
    finally:
        driver.quit()
    for name in ("studio", "panel"):
        if name in results:
            pooled = [x for run in results[name] for x in run.pop("latencies")]
            results[f"{name}_pooled"] = summary(pooled)
    # Frames the render thread made, by stride (1: whole; 2, 4: reduced while moving).
    results["frames_by_stride"] = {str(k): v for k, v in sorted(strides.items())}
    results["load_after"] = round(os.getloadavg()[0], 2)
    results["targets"] = TARGETS
    print(json.dumps(results, indent=2))
    if args.json:
        args.json.write_text(json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
