// The student page: a 3-D view (view3d.js, three.js), instruments, graphs from t = 0, settings and
// manual throttle of a live flight, all over the Foxglove protocol to `lander live`; or, served by
// `lander view BAG`, the replay of a recorded flight with a time slider (docs/live.md). Every
// control goes through the same server doors a Foxglove client uses, so the nodes validate and
// count it; every field shows the value in force in the flight, whoever set it (CLI, Foxglove,
// another page), except while the user is typing in it.
import { View3D } from "./view3d.js";

const MANUAL_RATE_HZ = 20;    // manual throttle resend rate (the sim's command hold is 0.5 s sim time)
const MAX_POINTS = 600;       // points drawn per line (the samples are decimated for drawing only)
const MAX_SAMPLES = 8000;     // samples kept for the graphs: past it every other one is dropped
const RAD2DEG = 180 / Math.PI;
const $ = (id) => document.getElementById(id);
let samples = [];             // graph records of this epoch, from t = 0
// Page-side counters, read by the browser test: states received and when (wall ms).
window.liveStats = { states: 0, times: [], last: null, messages: [], frames: 0 };
let lastRecord = null;
let view = null;
let manualThrottle = 0.0, manualTilt = 0.0;

function say(text, error) {
  $("message").textContent = text;
  $("message").className = error ? "error" : "";
  window.liveStats.messages.push(text);
}

async function start() {
  const cfg = await (await fetch("config.json")).json();
  view = new View3D($("view3d"));
  window.view3d = view;
  for (const el of document.querySelectorAll("input[name=camera]")) el.onchange = () => view.setMode(el.value);
  window.addEventListener("resize", () => view.resize());
  if (cfg.mode === "replay") await startReplay();
  else startLive(cfg);
  requestAnimationFrame(draw);
}

// --- live ----------------------------------------------------------------------------------------

function startLive(cfg) {
  const client = new FoxgloveClient(`ws://${location.hostname}:${cfg.ws_port}`);
  window.client = client;
  client.onOpen = () => { $("connection").textContent = "connected"; loadHistory(); };
  client.onClose = () => { $("connection").textContent = "disconnected (retrying)"; };
  client.onStatus = (msg) => say(msg.message, msg.level >= 2);
  client.onParameters = (params) => {
    for (const p of params) {
      if (p.name === "controller") reflect("controller-input", p.value);
      if (p.name === "controller_params") reflect("params-input", p.value);
      if (p.name === "demand_altitude") reflect("demand-input", p.value);
    }
  };
  client.subscribeJson("/live/state", onState);
  client.subscribeJson("/live/status", (s) => { $("refused").textContent = s.refused_total; });
  client.subscribeJson("/live/events", (e) => say(`event ${e.kind} at t = ${e.t.toFixed(2)} s ${e.detail || ""}`,
                                                    e.kind === "INPUT_REJECTED" || e.kind === "CRASHED"));
  setTimeout(() => client.getParameters([]), 500);
  wireControls(client);
}

// The flight's graph fields from t = 0 (the bridge keeps them): the page draws the whole flight
// however late it opens.
async function loadHistory() {
  try {
    const past = await (await fetch("history.json")).json();
    const first = samples.length ? samples[0].t : Infinity;
    samples = past.filter((r) => r.t < first).concat(samples);
    window.liveStats.history = past.length;
  } catch (e) { say(`history: ${e.message}`, true); }
}

function onState(rec) {
  const st = window.liveStats;
  st.states += 1; st.last = rec; st.times.push(performance.now());
  if (st.times.length > 600) st.times.shift();
  ingest(rec);
  display(rec);
}

// A record into the graphs and the 3-D view.
function ingest(rec) {
  if (samples.length && rec.t < samples[samples.length - 1].t) samples = [];  // reset: a new epoch
  samples.push(rec);
  if (samples.length > MAX_SAMPLES) samples = samples.filter((_, i) => i % 2 === 0 || i === samples.length - 1);
  lastRecord = rec;
  view.update(rec);
}

// Fixed decimals; a value that rounds to zero reads 0, never -0.
const fmt = (v, d) => (v === null || v === undefined || !isFinite(v) ? "-" : (Math.abs(v) < 0.5 * 10 ** -d ? 0 : v).toFixed(d));
const vec = (a, d, k = 1) => (a ? a.map((v) => fmt(k * v, d)).join(" ") : "-");

// A field shows the value in force unless the user is typing in it.
// Fields the user has typed into and not yet sent: the flight's values do not overwrite them
// (typing a controller, then its parameters, must not lose the controller typed first).
const edited = new Set();

function reflect(id, value) {
  const el = $(id);
  if (value === null || value === undefined || document.activeElement === el || edited.has(id)) return;
  const text = String(value);
  if (el.value !== text) el.value = text;
}

// The fields each button sends: once sent, they show the flight's values again.
const SENDS = { "demand-set": ["demand-input"], "switch": ["controller-input", "params-input"],
                "wind-set": ["wind-x", "wind-y", "wind-z"] };

function display(rec) {
  $("simtime").textContent = rec.t.toFixed(2);
  $("altitude").textContent = rec.altitude.toFixed(2);
  $("climb").textContent = rec.climb_rate.toFixed(3);
  $("demand").textContent = rec.demand_altitude === null ? "-" : rec.demand_altitude.toFixed(1);
  $("controller").textContent = rec.controller || "none";
  $("paused").textContent = rec.paused ? "PAUSED" : "";
  $("i-phase").textContent = rec.phase;
  $("i-fuel").textContent = fmt(rec.fuel, 2);
  $("i-ground-speed").textContent = fmt(rec.ground_speed, 2);
  $("i-tilt").textContent = fmt(rec.tilt === undefined ? null : rec.tilt * RAD2DEG, 1);
  $("i-rates").textContent = vec(rec.omega_B, 1, RAD2DEG);
  $("i-wind").textContent = vec(rec.wind_W, 1);
  $("i-throttles").textContent = vec(rec.throttles, 2);
  $("i-stabiliser").textContent = rec.stabiliser ? "on" : "off";
  $("i-parachute").textContent = rec.parachute ? "open" : "stowed";
  $("i-controller").textContent = rec.controller || "none";
  $("i-gains").textContent = rec.controller_params || (rec.controller ? "its defaults" : "-");
  reflect("demand-input", rec.demand_altitude);
  reflect("controller-input", rec.controller);
  reflect("params-input", rec.controller_params);
  if (rec.wind_W) ["wind-x", "wind-y", "wind-z"].forEach((id, i) => reflect(id, rec.wind_W[i]));
}

function wireControls(client) {
  const num = (id) => Number($(id).value);
  for (const [button, fields] of Object.entries(SENDS)) {
    for (const id of fields) $(id).addEventListener("input", () => edited.add(id));
    $(button).addEventListener("click", () => fields.forEach((id) => edited.delete(id)));
  }
  $("demand-set").onclick = async () => {
    const value = num("demand-input");
    const params = await client.setParameters([{ name: "demand_altitude", value, type: "float64" }]);
    const now = params.find((p) => p.name === "demand_altitude");
    if (now && now.value === value) say(`demand altitude set to ${value} m`, false);
  };
  $("demand-input").onkeydown = (ev) => { if (ev.key === "Enter") $("demand-set").click(); };
  $("wind-set").onclick = () => {
    client.publishJson("/lander/wind", { x: num("wind-x"), y: num("wind-y"), z: num("wind-z") });
    say("wind sent", false);
  };
  const service = (name, req) => client.callService(name, req)
    .then((r) => say(`${name}: ${r.success ? "ok" : "refused"} ${r.message || ""}`, !r.success))
    .catch((e) => say(`${name}: ${e.message}`, true));
  $("pause").onclick = () => service("/lander/pause", {});
  $("resume").onclick = () => service("/lander/resume", {});
  $("step").onclick = () => service("/lander/step", { steps: Math.max(1, Math.floor(num("step-n"))) });
  $("reset").onclick = () => service("/lander/reset", {});
  $("switch").onclick = () => service("/autopilot/switch_controller",
    { controller: $("controller-input").value, parameters_yaml: $("params-input").value });
  document.addEventListener("keydown", (ev) => {
    if (!$("manual").checked || ev.target.tagName === "INPUT" && ev.target.type !== "checkbox") return;
    const keys = { ArrowUp: [0.05, 0], ArrowDown: [-0.05, 0], ArrowLeft: [0, -0.05], ArrowRight: [0, 0.05] };
    if (ev.key === " ") { manualThrottle = 0; manualTilt = 0; }
    else if (keys[ev.key]) { manualThrottle += keys[ev.key][0]; manualTilt += keys[ev.key][1]; }
    else return;
    ev.preventDefault();
    manualThrottle = Math.min(1, Math.max(0, manualThrottle));
    manualTilt = Math.min(0.5, Math.max(-0.5, manualTilt));
    $("manual-throttle").textContent = `${manualThrottle.toFixed(2)} tilt ${manualTilt.toFixed(2)}`;
  });
  setInterval(() => {
    if (!$("manual").checked || !lastRecord) return;
    const n = lastRecord.throttles.length;
    // Tilt: thrusters on +x side (first half) against the others, clipped into [0, 1].
    const th = Array.from({ length: n }, (_, i) =>
      Math.min(1, Math.max(0, manualThrottle + (i < n / 2 ? manualTilt : -manualTilt))));
    client.publishJson("/lander/throttle", { throttles: th });
  }, 1000 / MANUAL_RATE_HZ);
}

// --- replay (lander view BAG) --------------------------------------------------------------------

const replay = { records: [], index: -1, playing: false, playT: 0, wall: 0 };
window.replay = replay;

async function startReplay() {
  document.body.classList.add("replay");
  $("mode-name").textContent = "replay";
  const data = await (await fetch("replay.json")).json();
  replay.records = data.records;
  $("connection").textContent = `scene ${data.scene}, ${data.records.length} states` + (data.note ? ` (${data.note})` : "");
  const slider = $("replay-slider");
  slider.max = String(data.records.length - 1);
  slider.oninput = () => { replay.playing = false; $("play").textContent = "play"; show(Number(slider.value)); };
  $("play").onclick = () => {
    if (replay.index >= replay.records.length - 1) show(0);
    replay.playing = !replay.playing;
    replay.playT = replay.records[Math.max(0, replay.index)].t;
    replay.wall = performance.now();
    $("play").textContent = replay.playing ? "pause" : "play";
  };
  show(0);
}

// Show the flight up to record i: forward, the records since the last one shown; back, from the start.
function show(i) {
  const recs = replay.records;
  i = Math.max(0, Math.min(recs.length - 1, i));
  if (i < replay.index) { samples = []; view.clearTrail(); view.last = null; replay.index = -1; }
  for (let k = replay.index + 1; k <= i; k++) ingest(recs[k]);
  replay.index = i;
  const rec = recs[i];
  window.liveStats.states = i + 1; window.liveStats.last = rec;
  display(rec);
  $("replay-slider").value = String(i);
  $("replay-time").textContent = `t = ${rec.t.toFixed(2)} / ${recs[recs.length - 1].t.toFixed(2)} s`;
}

function advanceReplay() {
  if (!replay.playing) return;
  const now = performance.now();
  replay.playT += (now - replay.wall) / 1000 * Number($("replay-speed").value);
  replay.wall = now;
  const recs = replay.records;
  let i = replay.index;
  while (i + 1 < recs.length && recs[i + 1].t <= replay.playT) i++;
  if (i !== replay.index) show(i);
  if (i >= recs.length - 1) { replay.playing = false; $("play").textContent = "play"; }
}

// --- graphs: rounded ticks, from t = 0 -----------------------------------------------------------

// A tick spacing of 1, 2 or 5 x 10^k giving about `n` intervals over `span`.
function niceStep(span, n) {
  const raw = span / n, p = 10 ** Math.floor(Math.log10(raw)), m = raw / p;
  return (m < 1.5 ? 1 : m < 3 ? 2 : m < 7 ? 5 : 10) * p;
}

// The axis of the values lo..hi: bounds on whole ticks and labels with just the decimals the step
// needs (so no two are equal). A flat range (hi = lo) is widened by 1 % of the value (at least
// 0.5) each side: the value then sits mid-axis with distinct labels above and below.
function axis(lo, hi, n = 4) {
  if (!(hi - lo > 1e-9 * Math.max(1, Math.abs(lo), Math.abs(hi)))) {
    const pad = Math.max(0.01 * Math.abs(lo), 0.5);
    lo -= pad; hi += pad;
  }
  const step = niceStep(hi - lo, n);
  const digits = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
  const a = Math.floor(lo / step + 1e-9) * step, b = Math.ceil(hi / step - 1e-9) * step;
  const ticks = [];
  for (let v = a; v <= b + step / 2; v += step) ticks.push({ value: v, label: (Math.abs(v) < step / 2 ? 0 : v).toFixed(digits) });
  return { lo: a, hi: b, step, ticks };
}
window.axes = { niceStep, axis };
// The sim time span of the graphs' samples [s] (the browser test: from t = 0 however late the page opened).
window.samplesSpan = () => (samples.length ? [samples[0].t, samples[samples.length - 1].t] : null);

const COLORS = ["#ffb070", "#70c0ff", "#90e090", "#e090e0", "#e0e070", "#f07070"];
window.graphBoxes = {};       // per graph: where its title and legend entries were drawn (browser test)

function plot(canvas, title, series, unit) {
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 56, B = 30, T = 22, R = 22;
  ctx.clearRect(0, 0, W, H);
  ctx.font = "12px sans-serif"; ctx.textBaseline = "alphabetic";
  const head = `${title} [${unit}]`;
  ctx.fillStyle = "#ccc"; ctx.fillText(head, 6, 14);
  // The legend starts after the title and its unit, so it never covers them.
  const boxes = { title: [6, 2, ctx.measureText(head).width, 14], legend: [] };
  let lx = 6 + boxes.title[2] + 18;
  series.forEach((s, k) => {
    const w = ctx.measureText(s.name).width;
    ctx.fillStyle = s.color || COLORS[k % COLORS.length];
    ctx.fillRect(lx, 8, 10, 3); ctx.fillText(s.name, lx + 13, 14);
    boxes.legend.push([lx, 2, w + 13, 14]);
    lx += w + 26;
  });
  window.graphBoxes[canvas.id] = boxes;
  if (samples.length < 2) return;
  const t0 = samples[0].t, t1 = Math.max(samples[samples.length - 1].t, t0 + 1e-3);
  let lo = Infinity, hi = -Infinity;
  const stride = Math.max(1, Math.ceil(samples.length / MAX_POINTS));
  for (const s of series) for (let i = 0; i < samples.length; i += stride) { const v = s.get(samples[i]); if (v !== null && v !== undefined && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }
  if (!isFinite(lo)) return;
  const ya = axis(lo, hi), xa = axis(Math.min(0, t0), t1, 6);
  const x = (t) => L + (W - L - R) * (t - xa.lo) / (xa.hi - xa.lo);
  const y = (v) => T + (H - B - T) * (ya.hi - v) / (ya.hi - ya.lo);
  ctx.strokeStyle = "#2a2d35"; ctx.fillStyle = "#aaa"; ctx.textAlign = "right";
  for (const tk of ya.ticks) {
    ctx.beginPath(); ctx.moveTo(L, y(tk.value)); ctx.lineTo(W - R, y(tk.value)); ctx.stroke();
    ctx.fillText(tk.label, L - 4, y(tk.value) + 4);
  }
  ctx.textAlign = "center";
  for (const tk of xa.ticks) {
    ctx.beginPath(); ctx.moveTo(x(tk.value), T); ctx.lineTo(x(tk.value), H - B); ctx.stroke();
    ctx.fillText(tk.label, x(tk.value), H - B + 14);
  }
  ctx.fillText("t [s]", W - 30, H - 3);
  ctx.textAlign = "left";
  window.graphBoxes[canvas.id].yLabels = ya.ticks.map((tk) => tk.label);
  window.graphBoxes[canvas.id].xLabels = xa.ticks.map((tk) => tk.label);
  series.forEach((s, k) => {
    ctx.strokeStyle = s.color || COLORS[k % COLORS.length]; ctx.beginPath();
    let moved = false;
    for (let i = 0; i < samples.length; i += stride) {
      const r = samples[i];
      const v = s.get(r); if (v === null || v === undefined || !isFinite(v)) continue;
      if (!moved) { ctx.moveTo(x(r.t), y(v)); moved = true; } else ctx.lineTo(x(r.t), y(v));
    }
    ctx.stroke();
  });
}

const GRAPH_PERIOD_MS = 100;  // the graphs are redrawn 10 times a second, the 3-D view every frame
let lastGraphs = -Infinity;

function draw(now) {
  window.liveStats.frames += 1;
  advanceReplay();
  view.render();
  if (now - lastGraphs >= GRAPH_PERIOD_MS) { lastGraphs = now; drawGraphs(); }
  requestAnimationFrame(draw);
}

function drawGraphs() {
  plot($("g-altitude"), "altitude", [
    { name: "altitude", get: (r) => r.altitude },
    { name: "demand", get: (r) => r.demand_altitude, color: "#5f5" }], "m");
  plot($("g-climb"), "climb rate", [{ name: "climb", get: (r) => r.climb_rate }], "m/s");
  plot($("g-attitude"), "ZXZ Euler angles", ["phi", "theta", "psi"].map((n, i) => ({ name: n, get: (r) => r.euler_zxz[i] * RAD2DEG })), "deg");
  const n = lastRecord ? lastRecord.throttles.length : 0;
  plot($("g-throttle"), "throttles", Array.from({ length: n }, (_, i) => ({ name: `#${i + 1}`, get: (r) => r.throttles[i] })), "0..1");
}

start().catch((e) => say(`cannot start: ${e.message}`, true));
