// The marble studio's page (issue 41): one websocket to mimarble/studio/server.py.
//
// Every control is generated from the session's controls() (the parameter table's kinds,
// ranges and choices): no parameter is named in this file. An edit is sent at once (the
// server's session renders the newest state only); the server answers each message
// ("edited" / "invalid" with the table's sentence / "done" / "problem") and sends frames
// as binary messages: a 4-byte big-endian header length, the JSON header, the image.
//
// window.studio holds what the browser tests and scripts/studio_browser_latency.py read:
// latencies (ms, edit sent -> its frame's image loaded), frames, and the longest gap
// between animation frames since the last reset (a page blocked by a long task).
"use strict";

const token = document.querySelector('meta[name="mimarble-token"]').content;
const studio = window.studio = {
  latencies: [], frames: [], problems: [], done: [], longestGap: 0, connected: false,
  version: 0, compilingSeen: false, state: null,
  resetGap() { this.longestGap = 0; },
  edit: (key, value) => edit(key, value),        // for scripts: as a control would
};

let socket = null;
let seq = 0;
const pending = [];          // edits sent: {seq, t0, version}
let controlsByKey = {};      // key -> control description
let keyOrder = "";           // the controls' keys, joined: same keys -> update in place
let histograms = [];
let frameUrl = null;
let scenePath = "";
let presets = [];             // the marble library: [{name, title, about}]

// ---- helpers -------------------------------------------------------------------------

const $ = (id) => document.getElementById(id);

function el(tag, attributes = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attributes)) {
    if (value === null || value === undefined || value === false) continue;
    if (name === "text") node.textContent = value;
    else node.setAttribute(name, value === true ? "" : String(value));
  }
  for (const child of children) node.append(child);
  return node;
}

function safeId(key) { return "c-" + key.replace(/[^A-Za-z0-9_-]/g, "_"); }

function say(text) { $("message").textContent = text; }

function send(message) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
}

// sRGB <-> linear: the colour pickers speak sRGB hex, the ramp's numbers are linear.
function toSrgbByte(linear) {
  const c = Math.min(1, Math.max(0, linear));
  const s = c <= 0.0031308 ? 12.92 * c : 1.055 * Math.pow(c, 1 / 2.4) - 0.055;
  return Math.round(s * 255);
}
function hexOf(rgb) {
  return "#" + rgb.map((c) => toSrgbByte(c).toString(16).padStart(2, "0")).join("");
}

// ---- the websocket -------------------------------------------------------------------

function connect() {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  socket = new WebSocket(`${scheme}//${location.host}/ws?token=${encodeURIComponent(token)}`);
  socket.binaryType = "arraybuffer";
  socket.onopen = () => { studio.connected = true; hideBanner("connection"); };
  socket.onclose = () => {
    studio.connected = false;
    showBanner("connection", "The studio's server is not reachable (stopped?). Reload the page when it runs again.");
  };
  socket.onmessage = (event) => {
    if (typeof event.data === "string") onMessage(JSON.parse(event.data));
    else onBinary(event.data);
  };
}

function onBinary(buffer) {
  const length = new DataView(buffer).getUint32(0);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, length)));
  const blob = new Blob([new Uint8Array(buffer, 4 + length)], { type: header.mime });
  if (header.type === "frame") onFrame(header, blob);
  else if (header.type === "compare") onCompare(header, blob);
}

function onMessage(m) {
  switch (m.type) {
    case "hello": presets = m.presets || []; keyOrder = ""; onControls(m.controls); onState(m.state); break;
    case "controls": onControls(m.controls); break;
    case "state": onState(m.state); break;
    case "histograms":
      histograms = (m.histograms && m.histograms.histograms) || [];
      drawHistograms();
      break;
    case "value": setValue(m.key, m.value); break;
    case "edited": {
      const p = pending.find((e) => e.seq === m.seq);
      if (p) p.version = m.version;
      clearError(m.key);
      break;
    }
    case "invalid": {
      const i = pending.findIndex((e) => e.seq === m.seq);
      if (i >= 0) pending.splice(i, 1);
      showError(m.key, m.message);
      break;
    }
    case "done": studio.done.push(m); say(m.message); break;
    case "reload": say("the scene was reloaded from its file"); break;
    case "problem": onProblem(m); break;
    case "pong": break;
  }
}

function onProblem(m) {
  studio.problems.push(m);
  say(m.message);
  if (m.action === "save" && /changed on disk|reload/i.test(m.message)) {
    showBanner("save", m.message, "Reload from disk", () => { send({ type: "reload" }); hideBanner("save"); });
  }
}

// ---- frames --------------------------------------------------------------------------

function onFrame(header, blob) {
  const arrived = performance.now();
  const url = URL.createObjectURL(blob);
  const img = $("frame");
  img.onload = () => {
    const now = performance.now();
    if (frameUrl) URL.revokeObjectURL(frameUrl);
    frameUrl = url;
    studio.version = header.version;
    studio.frames.push({ t: now, arrived, version: header.version, spp: header.spp });
    if (studio.frames.length > 2000) studio.frames.splice(0, 1000);
    // The newest edit this frame shows is timed; older ones it covers were never shown
    // on their own (dropped as stale), so they are not timed.
    let newest = -1;
    pending.forEach((p, i) => { if (p.version !== undefined && p.version <= header.version) newest = i; });
    if (newest >= 0) {
      studio.latencies.push(now - pending[newest].t0);
      for (let i = pending.length - 1; i >= 0; i--) {
        if (pending[i].version !== undefined && pending[i].version <= header.version) pending.splice(i, 1);
      }
    }
    const latest = studio.latencies.length ? studio.latencies[studio.latencies.length - 1] : null;
    $("latency").textContent = latest === null ? "" : `edit → screen ${latest.toFixed(0)} ms`;
  };
  img.src = url;
  $("spp").textContent = `${header.spp} / ${header.target_spp} spp` + (header.final ? "" : " (refining)");
  $("timing").textContent = `${header.width}×${header.height}, render ${fmt(header.render_ms)} ms`;
  if (header.histograms) { histograms = header.histograms; drawHistograms(); }
}

function fmt(x) { return typeof x === "number" ? x.toFixed(1) : "?"; }

function onState(s) {
  if (!s) return;
  studio.state = s;
  if (s.compiling) studio.compilingSeen = true;
  $("compiling").hidden = !s.compiling;
  $("dirty").hidden = !s.dirty;
  if (s.path) { scenePath = s.path; $("scene-path").textContent = s.path; }
  if (s.error) {
    const e = s.error;
    showBanner("parse", `${e.where || ""}: ${e.message}` + (e.hint ? ` — ${e.hint}` : "") +
               " (the last good render stays)");
  } else hideBanner("parse");
  if (s.disk_changed) {
    showBanner("disk", "The scene file changed on disk while you had unsaved edits (Save refuses).",
               "Reload from disk (drops the edits)", () => send({ type: "reload" }));
  } else hideBanner("disk");
  if (s.compare === "running") say("rendering the float64 reference…");
}

function onCompare(header, blob) {
  $("compare-box").hidden = false;
  const f = (x, d) => (typeof x === "number" ? x.toFixed(d) : "?");
  $("compare-figures").textContent = header.status === "done"
    ? `PSNR ${f(header.psnr, 2)} dB, RMSE ${f(header.rmse, 6)}, max ${f(header.max_abs, 5)} (${f(header.seconds, 1)} s)`
    : `compare ${header.status}` + (header.message ? `: ${header.message}` : "");
  if (header.note) $("compare-figures").textContent += ` — ${header.note}`;
  if (blob.size) $("compare-image").src = URL.createObjectURL(blob);
}

// ---- banners -------------------------------------------------------------------------

const banners = {};
function showBanner(name, text, action, onAction) {
  banners[name] = { text, action, onAction };
  renderBanner();
}
function hideBanner(name) { delete banners[name]; renderBanner(); }
function renderBanner() {
  const box = $("banner");
  box.replaceChildren();
  for (const b of Object.values(banners)) {
    const line = el("p", { text: b.text });
    if (b.action) {
      const button = el("button", { type: "button", text: b.action });
      button.addEventListener("click", b.onAction);
      line.append(" ", button);
    }
    box.append(line);
  }
  box.hidden = Object.keys(banners).length === 0;
}

// ---- controls ------------------------------------------------------------------------

function onControls(controls) {
  const list = controls.groups.flatMap((g) => g.controls);
  const order = list.map((c) => c.key + ":" + c.kind).join("|");
  const before = controlsByKey;
  controlsByKey = Object.fromEntries(list.map((c) => [c.key, c]));
  if (order === keyOrder) {                       // same controls: values only (keeps focus)
    for (const c of list) {
      if (c.kind === "colours") {                 // a ramp's editor is rebuilt when it changed
        if (!before[c.key] || before[c.key].text !== c.text) setValue(c.key, c.value);
      } else if (c.kind !== "stop") setValue(c.key, c.value);
    }
    return;
  }
  keyOrder = order;
  const focused = document.activeElement && document.activeElement.id;
  const box = $("controls");
  box.replaceChildren();
  controls.groups.forEach((group, i) => {
    // The first group (every marble, or the scene's only one) open; the others folded.
    const section = el("details", { class: "group", open: i === 0 || group.kind !== "marble" },
                       el("summary", { text: group.label || group.name }));
    if (group.kind === "marble" && presets.length) section.append(buildPresetPicker(group));
    for (const c of group.controls) {
      if (c.kind !== "stop") section.append(buildControl(c));   // stops: in the ramp editor
    }
    box.append(section);
  });
  if (focused && $(focused)) $(focused).focus();
  drawHistograms();
}

function edit(key, value) {
  const message = { type: "edit", key, value, seq: ++seq };
  pending.push({ seq: message.seq, t0: performance.now() });
  if (pending.length > 500) pending.splice(0, 250);
  send(message);
}

function errorBox(key) { return el("span", { class: "error", id: safeId(key) + "-error", role: "alert" }); }
function showError(key, text) {
  const box = $(safeId(key) + "-error") || $(safeId(rampKeyOf(key)) + "-error");
  if (box) box.textContent = text; else say(text);
  const input = $(safeId(key)); if (input) input.setAttribute("aria-invalid", "true");
}
function clearError(key) {
  for (const k of [key, rampKeyOf(key)]) {
    const box = $(safeId(k) + "-error"); if (box) box.textContent = "";
    const input = $(safeId(k)); if (input) input.removeAttribute("aria-invalid");
  }
}
function rampKeyOf(key) { return key.replace(/\.ramp\.\d+$/, ".ramp"); }

function buildControl(c) {
  const id = safeId(c.key);
  const row = el("div", { class: "control", "data-key": c.key, title: c.doc || "" });
  const label = el("label", { for: id, text: c.label || c.key });
  switch (c.kind) {
    case "number": case "integer": {
      const [lo, hi] = sliderRange(c);
      const step = c.kind === "integer" ? 1 : (c.step || (hi - lo) / 200);
      const slider = el("input", { type: "range", id, min: lo, max: hi, step, value: c.value });
      const typed = el("input", { type: "text", inputmode: "decimal", class: "typed",
                                  id: id + "-typed", "aria-label": `${c.label || c.key} (typed)`,
                                  value: c.value });
      slider.addEventListener("input", () => {
        typed.value = slider.value;
        edit(c.key, c.kind === "integer" ? parseInt(slider.value, 10) : parseFloat(slider.value));
      });
      typed.addEventListener("change", () => {
        const text = typed.value.trim();
        if (text === "") return;                  // an emptied box is no value yet
        const number = Number(text);
        if (Number.isFinite(number)) slider.value = number;
        edit(c.key, Number.isFinite(number) ? number : text);
      });
      row.append(label, slider, typed);
      break;
    }
    case "choice": case "mode": {
      const select = el("select", { id });
      for (const choice of c.choices || []) select.append(el("option", { value: choice, text: choice }));
      select.value = c.value;
      select.addEventListener("change", () => edit(c.key, select.value));
      row.append(label, select);
      break;
    }
    case "boolean": {
      const box = el("input", { type: "checkbox", id });
      box.checked = !!c.value;
      box.addEventListener("change", () => edit(c.key, box.checked));
      row.append(label, box);
      break;
    }
    case "colour": {
      const picker = el("input", { type: "color", id, value: colourHex(c.value) });
      picker.addEventListener("input", () => edit(c.key, picker.value));
      row.append(label, picker);
      break;
    }
    case "colours": row.append(buildRamp(c)); break;
    default: {                                   // vector, size, positions…: the value's text
      const text = el("input", { type: "text", id, value: valueText(c.value) });
      text.addEventListener("change", () => edit(c.key, text.value));
      row.append(label, text);
    }
  }
  row.append(errorBox(c.key));
  return row;
}

// The marble library's picker of a marble group: the group's key prefix is its controls'
// keys less their parameter's name ("stone.diffuse.period" → "stone.diffuse").
function buildPresetPicker(group) {
  const first = group.controls.find((c) => c.name && c.key.endsWith("." + c.name));
  const row = el("div", { class: "control" });
  if (!first) return row;
  const prefix = first.key.slice(0, -(first.name.length + 1));
  const id = safeId(prefix + ".preset");
  const select = el("select", { id });
  select.append(el("option", { value: "", text: "—" }));
  for (const p of presets) select.append(el("option", { value: p.name, text: p.title, title: p.about }));
  select.addEventListener("change", () => {
    if (select.value) send({ type: "preset", prefix, name: select.value });
  });
  row.append(el("label", { for: id, text: `${prefix} preset` }), select);
  return row;
}

function sliderRange(c) {
  if (Array.isArray(c.slider) && c.slider.length === 2) return c.slider;
  const v = Number(c.value) || 1;
  const lo = c.min ?? Math.min(0, v * 2), hi = c.max ?? Math.max(v * 2, 1);
  return [lo, hi];
}

function valueText(v) {
  if (Array.isArray(v)) return v.map(valueText).join(" ");
  return v === null || v === undefined ? "" : String(v);
}

function colourHex(v) {
  if (typeof v === "string" && /^#[0-9a-f]{6}$/i.test(v.trim())) return v.trim().toLowerCase();
  const numbers = Array.isArray(v) ? v.flat().map(Number) : String(v).replace(/[<>,]/g, " ").trim().split(/\s+/).map(Number);
  return numbers.length >= 3 && numbers.every(Number.isFinite) ? hexOf(numbers.slice(-3)) : "#000000";
}

function setValue(key, value) {
  const c = controlsByKey[key];
  if (c) c.value = value;
  if (c && c.kind === "colours") {             // a whole ramp: rebuild its editor
    const old = document.querySelector(`[data-ramp="${CSS.escape(key)}"]`);
    if (old) old.replaceWith(buildRamp(c));
    drawHistograms();
    return;
  }
  const input = $(safeId(key));
  if (!input || input === document.activeElement) return;
  if (input.type === "checkbox") input.checked = !!value;
  else if (input.type === "color") input.value = colourHex(value);
  else input.value = valueText(value);
  const typed = $(safeId(key) + "-typed");
  if (typed && typed !== document.activeElement) typed.value = valueText(value);
  if (typed) clearError(key);
}

// ---- the ramp editor -----------------------------------------------------------------

// A ramp control as stops {position, text (the colour exactly as the scene writes it, from
// the control's text), hex (for the picker)}; its value is {colors, positions, explicit}.
function parseRamp(c) {
  const v = c.value || {};
  const colors = v.colors || [], positions = v.positions || [];
  const items = String(c.text || "").split(",").map((item) => item.trim());
  return colors.map((hex, i) => {
    let text = items.length === colors.length ? items[i] : hex;
    if (v.explicit) {               // "p r g b" or "p #rrggbb": the colour is what follows p
      const words = text.split(/\s+/);
      text = words.length === 4 || words.length === 2 ? words.slice(1).join(" ") : text;
    }
    return { position: positions[i] ?? null, text, hex };
  });
}

// Stops as the ramp's value text: positions written when the ramp had them or one moved.
function rampText(stops, explicit) {
  return stops.map((s, i) => {
    if (!explicit) return s.text;
    const p = s.position ?? (stops.length > 1 ? i / (stops.length - 1) : 0);
    return `${+Number(p).toFixed(4)} ${s.text}`;
  }).join(", ");
}

function buildRamp(c) {
  const stops = parseRamp(c);
  const explicit = !!(c.value && c.value.explicit);
  const prefix = c.key.replace(/\.ramp$/, "");
  const name = c.label || c.key;
  const box = el("div", { class: "ramp-editor", "data-ramp": c.key, role: "group", "aria-label": name });
  box.append(el("span", { class: "ramp-title", id: safeId(c.key), tabindex: -1, text: name }));
  const whole = (list, positioned) => { edit(c.key, rampText(list, positioned)); };
  stops.forEach((stop, i) => {
    const position = el("input", { type: "number", min: 0, max: 1, step: 0.01, class: "position",
                                   value: +Number(stop.position ?? 0).toFixed(4),
                                   "aria-label": `${name} stop ${i} position` });
    const picker = el("input", { type: "color", value: stop.hex, "aria-label": `${name} stop ${i} colour` });
    const remove = el("button", { type: "button", class: "remove", text: "−",
                                  "aria-label": `${name}: remove stop ${i}`, disabled: stops.length <= 1 });
    // A moved stop: the whole ramp with every position (the scene says all or none).
    position.addEventListener("change", () => {
      const list = stops.map((s, j) => (j === i ? { ...s, position: Number(position.value) } : s));
      whole(list, true);
    });
    // A new colour: that stop alone (its key X.ramp.N), the other stops' text untouched.
    picker.addEventListener("input", () => edit(`${c.key}.${i}`, picker.value));
    remove.addEventListener("click", () => whole(stops.filter((_, j) => j !== i), explicit));
    box.append(el("div", { class: "stop" }, position, picker, remove));
  });
  const add = el("button", { type: "button", class: "add", text: "+ colour", "aria-label": `${name}: add a colour` });
  add.addEventListener("click", () => {
    const last = stops[stops.length - 1];
    whole(stops.concat([{ position: 1, text: last ? last.text : "#ffffff", hex: last ? last.hex : "#ffffff" }]), explicit);
  });
  box.append(add);
  box.append(el("canvas", { class: "histogram", width: 280, height: 70, "data-prefix": prefix,
                            role: "img", "aria-label": `${name}: distribution of t over the visible marble` }));
  return box;
}

// ---- the histogram of t, against the ramp's stops ----------------------------------

function drawHistograms() {
  for (const canvas of document.querySelectorAll("canvas.histogram")) {
    const prefix = canvas.dataset.prefix;
    const h = histograms.find((x) => (x.keys || []).includes(prefix)) ||
              histograms.find((x) => (x.keys || []).some((k) => k.startsWith(prefix + ".") || prefix.startsWith(k + "."))) ||
              (histograms.length === 1 ? histograms[0] : null);
    drawHistogram(canvas, h);
  }
}

function drawHistogram(canvas, h) {
  const g = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, strip = 10;
  g.clearRect(0, 0, W, H);
  if (!h) { g.fillStyle = "#888"; g.fillText("no marble in view", 4, 14); return; }
  const stops = h.stops || [], colours = h.colors || [];
  const gradient = g.createLinearGradient(0, 0, W, 0);
  stops.forEach((s, i) => gradient.addColorStop(Math.min(1, Math.max(0, s)), colours[i] || "#000"));
  g.fillStyle = stops.length ? gradient : "#444";
  g.fillRect(0, H - strip, W, strip);
  const counts = h.counts || [];
  const top = Math.max(1, ...counts);
  const bar = W / Math.max(1, counts.length);
  g.fillStyle = "#bbb";
  counts.forEach((n, i) => {
    const height = (H - strip - 2) * n / top;
    g.fillRect(i * bar, H - strip - height, Math.max(1, bar - 1), height);
  });
  stops.forEach((s, i) => {
    g.fillStyle = colours[i] || "#000";
    g.fillRect(Math.round(s * (W - 2)), 0, 2, H - strip);
  });
}

// ---- orbit, zoom, buttons --------------------------------------------------------------

function setupView() {
  const img = $("frame");
  let drag = null, dx = 0, dy = 0, scheduled = false;
  const flush = () => {
    scheduled = false;
    if (dx || dy) send({ type: "orbit", dx: -dx * 0.4, dy: dy * 0.4 });
    dx = dy = 0;
  };
  img.addEventListener("pointerdown", (e) => { drag = { x: e.clientX, y: e.clientY }; img.setPointerCapture(e.pointerId); });
  img.addEventListener("pointermove", (e) => {
    if (!drag) return;
    dx += e.clientX - drag.x; dy += e.clientY - drag.y;
    drag = { x: e.clientX, y: e.clientY };
    if (!scheduled) { scheduled = true; requestAnimationFrame(flush); }
  });
  const end = () => { drag = null; };
  img.addEventListener("pointerup", end);
  img.addEventListener("pointercancel", end);
  img.addEventListener("wheel", (e) => {
    e.preventDefault();
    send({ type: "zoom", factor: Math.exp(-e.deltaY * 0.0015) });
  }, { passive: false });

  const stem = () => (scenePath.split("/").pop() || "scene").replace(/\.scene$/, "");
  $("save").addEventListener("click", () => send({ type: "save" }));
  $("save-as").addEventListener("click", () => {
    const path = prompt("Save the scene as (relative to the scene's folder):", `${stem()}-edited.scene`);
    if (path) send({ type: "save_as", path });
  });
  $("snapshot").addEventListener("click", () => {
    const path = prompt("Snapshot of the current frame (PNG or JPEG):", `${stem()}-snapshot.png`);
    if (path) send({ type: "snapshot", path });
  });
  $("export").addEventListener("click", () => {
    const path = prompt("Export to Mitsuba XML (.xml) or Python (.py):", `${stem()}.xml`);
    if (path) send({ type: "export", path, python: /\.py$/i.test(path) });
  });
  $("compare").addEventListener("click", () => send({ type: "compare" }));
}

// The longest gap between animation frames (a page blocked by a long task shows here).
let lastFrameTime = null;
function watchGaps(now) {
  if (lastFrameTime !== null) studio.longestGap = Math.max(studio.longestGap, now - lastFrameTime);
  lastFrameTime = now;
  requestAnimationFrame(watchGaps);
}

setupView();
connect();
requestAnimationFrame(watchGaps);
