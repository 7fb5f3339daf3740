// The student page: graphs, settings, manual throttle and a 2-D view of a live flight, all over
// the Foxglove protocol to `lander live` (docs/live.md). Every control goes through the same
// server doors a Foxglove client uses, so the nodes validate and count it.
"use strict";

const WINDOW_S = 60;          // seconds of sim time shown in the graphs
const MANUAL_RATE_HZ = 20;
const MAX_POINTS = 600;       // points drawn per line (the samples are decimated for drawing only)    // manual throttle resend rate (the sim's command hold is 0.5 s sim time)
const $ = (id) => document.getElementById(id);
const samples = [];           // state records in the graph window
// Page-side counters, read by the browser test: states received and when (wall ms).
window.liveStats = { states: 0, times: [], last: null, messages: [] };
let lastRecord = null;
let manualThrottle = 0.0, manualTilt = 0.0;

function say(text, error) {
  $("message").textContent = text;
  $("message").className = error ? "error" : "";
  window.liveStats.messages.push(text);
}

async function start() {
  const cfg = await (await fetch("config.json")).json();
  const client = new FoxgloveClient(`ws://${location.hostname}:${cfg.ws_port}`);
  window.client = client;
  client.onOpen = () => { $("connection").textContent = "connected"; };
  client.onClose = () => { $("connection").textContent = "disconnected (retrying)"; };
  client.onStatus = (msg) => say(msg.message, msg.level >= 2);
  client.onParameters = (params) => {
    for (const p of params) {
      if (p.name === "controller" && document.activeElement !== $("controller-input")) $("controller-input").value = p.value;
      if (p.name === "controller_params" && document.activeElement !== $("params-input")) $("params-input").value = p.value;
    }
  };
  client.subscribeJson("/live/state", onState);
  client.subscribeJson("/live/status", (s) => { $("refused").textContent = s.refused_total; });
  client.subscribeJson("/live/events", (e) => say(`event ${e.kind} at t = ${e.t.toFixed(2)} s ${e.detail || ""}`,
                                                    e.kind === "INPUT_REJECTED" || e.kind === "CRASHED"));
  setTimeout(() => client.getParameters([]), 500);
  wireControls(client);
  requestAnimationFrame(draw);
}

function onState(rec) {
  const st = window.liveStats;
  st.states += 1; st.last = rec; st.times.push(performance.now());
  if (st.times.length > 600) st.times.shift();
  if (samples.length && rec.t < samples[samples.length - 1].t) samples.length = 0;  // reset: a new epoch
  samples.push(rec);
  while (samples.length && samples[0].t < rec.t - WINDOW_S) samples.shift();
  lastRecord = rec;
  $("simtime").textContent = rec.t.toFixed(2);
  $("altitude").textContent = rec.altitude.toFixed(2);
  $("climb").textContent = rec.climb_rate.toFixed(3);
  $("demand").textContent = rec.demand_altitude === null ? "-" : rec.demand_altitude.toFixed(1);
  $("controller").textContent = rec.controller || "none";
  $("paused").textContent = rec.paused ? "PAUSED" : "";
}

function wireControls(client) {
  const num = (id) => Number($(id).value);
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

// --- drawing -----------------------------------------------------------------------------------

const COLORS = ["#ffb070", "#70c0ff", "#90e090", "#e090e0", "#e0e070", "#f07070"];

function plot(canvas, title, series, unit) {
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 52, B = 18;
  ctx.clearRect(0, 0, W, H);
  ctx.fillStyle = "#ccc"; ctx.font = "12px sans-serif";
  ctx.fillText(`${title} [${unit}]`, L, 13);
  if (samples.length < 2) return;
  const t0 = samples[0].t, t1 = Math.max(samples[samples.length - 1].t, t0 + 1e-3);
  let lo = Infinity, hi = -Infinity;
  const step = Math.max(1, Math.ceil(samples.length / MAX_POINTS));
  for (const s of series) for (let i = 0; i < samples.length; i += step) { const v = s.get(samples[i]); if (v !== null && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }
  if (!isFinite(lo)) return;
  if (hi - lo < 1e-6) { lo -= 0.5; hi += 0.5; }
  const pad = 0.05 * (hi - lo); lo -= pad; hi += pad;
  const x = (t) => L + (W - L - 6) * (t - t0) / (t1 - t0);
  const y = (v) => 18 + (H - B - 18) * (hi - v) / (hi - lo);
  ctx.strokeStyle = "#3a3d45"; ctx.beginPath(); ctx.moveTo(L, 18); ctx.lineTo(L, H - B); ctx.lineTo(W, H - B); ctx.stroke();
  ctx.fillText(hi.toPrecision(5), 2, 24); ctx.fillText(lo.toPrecision(5), 2, H - B);
  ctx.fillText(`t = ${t0.toFixed(1)} .. ${t1.toFixed(1)} s`, W - 150, H - 4);
  // At most ~MAX_POINTS points per line: drawing every state of a fast flight would cost the
  // page (and, headless, the machine) more than the data is worth.
  const stride = Math.max(1, Math.ceil(samples.length / MAX_POINTS));
  series.forEach((s, k) => {
    ctx.strokeStyle = s.color || COLORS[k % COLORS.length]; ctx.beginPath();
    let moved = false;
    for (let i = 0; i < samples.length; i += stride) {
      const r = samples[i];
      const v = s.get(r); if (v === null || !isFinite(v)) continue;
      if (!moved) { ctx.moveTo(x(r.t), y(v)); moved = true; } else ctx.lineTo(x(r.t), y(v));
    }
    ctx.stroke();
    ctx.fillStyle = ctx.strokeStyle; ctx.fillText(s.name, L + 130 + 70 * k, 13);
  });
}

function drawView(canvas) {
  // 2-D side view in the local surface frame: x horizontal, altitude up; the body tilted as its
  // z axis (up_S), plumes scaled by throttle.
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height;
  ctx.clearRect(0, 0, W, H);
  const r = lastRecord; if (!r) return;
  const span = Math.max(50, 1.3 * Math.max(r.altitude, r.demand_altitude || 0));
  const scale = (H - 30) / span;
  const gx = W / 2, gy = H - 15;
  ctx.fillStyle = "#7a3b20"; ctx.fillRect(0, gy, W, 15);
  if (r.demand_altitude !== null) {
    ctx.strokeStyle = "#5f5"; ctx.setLineDash([6, 4]); ctx.beginPath();
    ctx.moveTo(0, gy - r.demand_altitude * scale); ctx.lineTo(W, gy - r.demand_altitude * scale); ctx.stroke();
    ctx.setLineDash([]);
  }
  ctx.strokeStyle = "#3a8"; ctx.beginPath();
  const stride = Math.max(1, Math.ceil(samples.length / MAX_POINTS));
  samples.forEach((s, i) => { if (i % stride) return; const px = gx + ((s.position_S ? s.position_S[0] : 0) - (r.position_S ? r.position_S[0] : 0)) * scale, py = gy - s.altitude * scale; if (i) ctx.lineTo(px, py); else ctx.moveTo(px, py); });
  ctx.stroke();
  const ang = r.up_S ? Math.atan2(r.up_S[0], r.up_S[2]) : 0;
  ctx.save(); ctx.translate(gx, gy - r.altitude * scale); ctx.rotate(ang);
  const size = 14;
  ctx.fillStyle = "#ddd"; ctx.fillRect(-size, -size * 0.6, 2 * size, 1.2 * size);
  const n = r.throttles.length;
  r.throttles.forEach((u, i) => {
    const px = -size + (2 * size) * (i + 0.5) / n;
    ctx.fillStyle = "#ff8020"; ctx.fillRect(px - 3, size * 0.6, 6, 40 * u);
  });
  if (r.parachute) { ctx.strokeStyle = "#eef"; ctx.beginPath(); ctx.arc(0, -3 * size, 2 * size, Math.PI, 0); ctx.stroke(); }
  ctx.restore();
  ctx.fillStyle = "#ccc"; ctx.fillText(`view: ${span.toFixed(0)} m tall, phase ${r.phase}`, 8, 14);
}

function draw() {
  plot($("g-altitude"), "altitude", [
    { name: "altitude", get: (r) => r.altitude },
    { name: "demand", get: (r) => r.demand_altitude, color: "#5f5" }], "m");
  plot($("g-climb"), "climb rate", [{ name: "climb", get: (r) => r.climb_rate }], "m/s");
  plot($("g-attitude"), "ZXZ Euler angles", ["phi", "theta", "psi"].map((n, i) => ({ name: n, get: (r) => r.euler_zxz[i] * 180 / Math.PI })), "deg");
  const n = lastRecord ? lastRecord.throttles.length : 0;
  plot($("g-throttle"), "throttles", Array.from({ length: n }, (_, i) => ({ name: `#${i + 1}`, get: (r) => r.throttles[i] })), "0..1");
  drawView($("view"));
  requestAnimationFrame(draw);
}

start().catch((e) => say(`cannot start: ${e.message}`, true));
