// mlink-sim's live page (docs/web.md): reads GET plots.json (the plotting vocabulary) and GET api/network once, then
// the event stream api/events (the last minute of samples first, then status at most ten times a second and the
// network's events as they happen); the controls call the API. No build step, no framework: the plots are uPlot
// (static/vendor/uplot).
"use strict";

const WINDOW_S = 60;            // the stations' plots: the last minute
const NET_WINDOW_S = 600;       // the network's plot: the last ten minutes
const PLOT_EVERY_MS = 250;      // plots are redrawn at most four times a second (and only those in view)
const MAX_EVENTS = 300;
const MAX_MARKS = 200;          // marks kept per station (those in the window are drawn)
const MAX_LISTED = 12;          // marks listed under a station's plots (the newest in the window)

// early: the events that came before their station's panel (numbered once it is there)
const state = { token: null, stations: new Map(), net: null, netPlot: null, lastPlot: 0, vocab: null, early: [] };

// ---- the token: from the address's fragment (#token=…, never sent to a server), kept for this tab only
(function takeToken() {
  const m = location.hash.match(/token=([^&]+)/);
  if (m) {
    sessionStorage.setItem("mlink-token", decodeURIComponent(m[1]));
    history.replaceState(null, "", location.pathname + location.search);
  }
  state.token = sessionStorage.getItem("mlink-token");
})();

function headers(json) {
  const h = {};
  if (state.token) h.Authorization = "Bearer " + state.token;
  if (json) h["Content-Type"] = "application/json";
  return h;
}

class ApiError extends Error {}

async function api(method, path, body) {
  const init = { method, headers: headers(body !== undefined), cache: "no-store" };
  if (body !== undefined) init.body = JSON.stringify(body);
  const r = await fetch(path, init);
  let data = null;
  try { data = await r.json(); } catch (e) { /* not JSON */ }
  if (r.status === 401) askToken();
  if (!r.ok) throw new ApiError((data && data.error) || `${r.status} ${r.statusText}`);
  return data;
}

function askToken() {
  const form = document.getElementById("token-form");
  form.hidden = false;
  setLink("token needed", "bad");
}

document.getElementById("token-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  state.token = document.getElementById("token-input").value.trim();
  sessionStorage.setItem("mlink-token", state.token);
  document.getElementById("token-form").hidden = true;
  start();
});

function setLink(text, cls) {
  const el = document.getElementById("link-state");
  el.textContent = text;
  el.className = "badge " + cls;
}

// ---- formatting
const fmt = (v, digits = 1) => (v === null || v === undefined ? "–" : Number(v).toFixed(digits));
function setText(el, text) { if (el.textContent !== text) el.textContent = text; }

// ---- plots, in the plotting vocabulary the HTML report shares (GET plots.json: mlink_sim/plots.py)
const compact = (u, vals) => vals.map((v) => (v === null ? "" : Math.abs(v) >= 10000 ? `${v / 1000}k` : String(v)));

// the time axis in seconds at any window: as many decimals as the ticks' step needs (0.05 s apart: 4.05, 4.10 …;
// 2.5 s apart: 2.5, 5.0 …)
function decimals(incr) {
  for (let d = 0; d < 3; d++) {
    const x = incr * 10 ** d;
    if (Math.abs(x - Math.round(x)) < 1e-6 * Math.max(1, x)) return d;
  }
  return 3;
}

function timeAxis() {
  return {
    label: state.vocab.time_label, labelSize: 14, labelGap: 0, size: 30,
    values: (u, splits, axis, space, incr) => {
      const labels = splits.map((v) => (v === null ? "" : v.toFixed(decimals(incr))));
      u.root.dataset.xTicks = labels.join(" ");
      return labels;
    },
  };
}

function plotOptions(el, series, axes, hooks) {
  return {
    width: Math.max(200, el.clientWidth || 300), height: 140,
    cursor: { drag: { x: false, y: false } },
    legend: { live: false },
    scales: { x: { time: false } },
    series: [{ label: state.vocab.time_label }, ...series],
    axes: [timeAxis(), ...axes.map((a) => ({ values: compact, space: 18, ...a }))],  // a label every 18 px at least
    hooks: hooks || {},
  };
}

const seriesOf = (s, scale) => ({ label: s.label, scale, stroke: s.color, width: s.dash ? 1.5 : 2,
  ...(s.dash ? { dash: [5, 4] } : {}) });

function hzPlot(el, st) {
  const p = state.vocab.station_plots[0];
  return new uPlot(plotOptions(el, p.series.map((s) => seriesOf(s, "hz")), [{ scale: "hz", size: 42 }],
    overlay(st)), st.hzData, el);
}

function powerPlot(el, st) {
  const [current, bus] = state.vocab.station_plots.slice(1);
  return new uPlot(plotOptions(el, [...current.series.map((s) => seriesOf(s, "A")),
    ...bus.series.map((s) => seriesOf(s, "V"))],
  [{ scale: "A", size: 42 }, { scale: "V", side: 1, size: 46, grid: { show: false } }], overlay(st)), st.powerData, el);
}

function netPlot(el) {
  return new uPlot(plotOptions(el, [
    { label: "RTT p99 µs", scale: "us", stroke: "#1f6feb", width: 1.5 },
    { label: "missed", scale: "n", stroke: "#cf222e", width: 1.5 },
  ], [{ scale: "us", size: 46 }, { scale: "n", side: 1, size: 42, grid: { show: false } }]), [[], [], []], el);
}

// a station's columns: every figure the plots and the bands read, trimmed to the window together
const COLUMNS = ["reference_hz", "output_hz", "output_current_a", "dc_bus_v", "regulation"];

function pushRow(cols, t, values, windowS) {
  cols[0].push(t);
  values.forEach((v, i) => cols[i + 1].push(v === undefined ? null : v));
  let cut = 0;
  while (cut < cols[0].length && cols[0][cut] < t - windowS) cut++;
  if (cut) cols.forEach((c) => c.splice(0, cut));
}

function pushSample(st, t, row) {
  pushRow(st.cols, t, COLUMNS.map((k) => row[k]), WINDOW_S);
  st.dirty = true;
}

// the drive's regulation as bands: a state off for less than bridge_s between two samples that have it is one band
function bandsOf(st) {
  const [ts, reg] = [st.cols[0], st.cols[COLUMNS.length]];
  const bridge = state.vocab.bridge_s, out = [], open = new Map();
  for (let i = 0; i < ts.length; i++) {
    const now = reg[i] || [];
    for (const [name, span] of open) {
      if (!now.includes(name) && ts[i] - span.t1 > bridge) { out.push({ name, ...span }); open.delete(name); }
    }
    for (const name of now) {
      const span = open.get(name);
      if (span) span.t1 = ts[i]; else open.set(name, { t0: ts[i], t1: ts[i] });
    }
  }
  for (const [name, span] of open) out.push({ name, ...span });
  return out;
}

function overlay(st) {
  return { drawAxes: [(u) => drawBands(u, st)], draw: [(u) => drawMarks(u, st)] };
}

function drawBands(u, st) {
  const { ctx, bbox } = u, x = u.scales.x;
  ctx.save();
  ctx.globalAlpha = 0.45;
  for (const b of st.bands) {
    const a = Math.max(b.t0, x.min), z = Math.min(b.t1, x.max);
    if (z < a) continue;
    const pa = u.valToPos(a, "x", true), pz = u.valToPos(z, "x", true);
    ctx.fillStyle = (state.vocab.bands[b.name] || state.vocab.bands.fault).color;
    ctx.fillRect(pa, bbox.top, Math.max(pz - pa, 1), bbox.height);
  }
  ctx.restore();
}

// each mark: a line, its number in a circle at the top; circles that would overlap move down a row
function drawMarks(u, st) {
  if (u === st.hzPlot) st.node.dataset.xTicks = u.root.dataset.xTicks || "";
  const { ctx, bbox } = u, x = u.scales.x, dpr = devicePixelRatio || 1, r = 7 * dpr;
  const last = [-1e9, -1e9, -1e9];
  ctx.save();
  ctx.font = `bold ${9 * dpr}px system-ui, sans-serif`;
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  for (const m of st.marks) {
    if (m.t < x.min || m.t > x.max) continue;
    const px = u.valToPos(m.t, "x", true);
    let row = last.findIndex((p) => px - p >= 2 * r + dpr);
    if (row < 0) row = last.length - 1;
    last[row] = px;
    const py = bbox.top + r + dpr + row * (2 * r + 2 * dpr);
    const color = state.vocab.marks[m.kind].color;
    ctx.strokeStyle = color;
    ctx.globalAlpha = 0.8;
    ctx.lineWidth = dpr;
    ctx.beginPath(); ctx.moveTo(px, bbox.top); ctx.lineTo(px, bbox.top + bbox.height); ctx.stroke();
    ctx.globalAlpha = 1;
    ctx.fillStyle = color;
    ctx.beginPath(); ctx.arc(px, py, r, 0, 2 * Math.PI); ctx.fill();
    ctx.fillStyle = "#fff";
    ctx.fillText(String(m.n), px, py + 0.5 * dpr);
  }
  ctx.restore();
}

const visible = new IntersectionObserver((entries) => {
  for (const e of entries) {
    const st = state.stations.get(e.target.dataset.address);
    if (st) st.visible = e.isIntersecting;
  }
});

const resized = new ResizeObserver((entries) => {
  for (const e of entries) {
    const plot = e.target._plot;
    if (plot) plot.setSize({ width: Math.max(200, e.contentRect.width), height: 140 });
  }
});

// the marks and bands in the plots' window, listed under them with what each is (as the HTML report does)
function showLegend(st) {
  const from = st.cols[0].length ? st.cols[0][0] : -Infinity;
  const marks = st.marks.filter((m) => m.t >= from).slice(-MAX_LISTED);
  const key = marks.map((m) => m.n).join() + "|" + [...new Set(st.bands.map((b) => b.name))].join();
  if (st.legendKey === key) return;
  st.legendKey = key;
  st.legend.replaceChildren(...marks.map((m) => {
    const li = document.createElement("li");
    li.dataset.n = m.n;
    li.dataset.kind = m.kind;
    const n = document.createElement("span");
    n.className = "n";
    n.style.background = state.vocab.marks[m.kind].color;
    n.textContent = m.n;
    li.append(n, document.createTextNode(`${fmt(m.t, 1)} s ${m.text}`));
    return li;
  }));
  const shaded = [...new Set(st.bands.map((b) => b.name))];
  st.node.dataset.bands = shaded.join(" ");
  st.bandLegend.replaceChildren(...shaded.map((name) => {
    const span = document.createElement("span");
    const sw = document.createElement("i");
    sw.className = "sw";
    sw.style.background = state.vocab.bands[name].color;
    span.append(sw, document.createTextNode(state.vocab.bands[name].label));
    return span;
  }));
}

function redraw(st) {
  st.bands = bandsOf(st);
  st.hzPlot.setData(st.hzData);
  st.powerPlot.setData(st.powerData);
  const ts = st.cols[0];
  st.node.dataset.plotPoints = String(ts.length);
  st.node.dataset.plotFrom = ts.length ? String(ts[0]) : "";
  st.node.dataset.plotTo = ts.length ? String(ts[ts.length - 1]) : "";
  showLegend(st);
  st.dirty = false;
}

// ---- station panels
function addStation(info) {
  const node = document.getElementById("station-template").content.firstElementChild.cloneNode(true);
  node.dataset.address = info.address;
  node.id = "station-" + info.name;
  node.querySelector(".st-name").textContent = info.name;
  node.querySelector(".st-card").textContent = `${info.card.toUpperCase()} · ${info.link}` +
    (info.frame_size ? ` · ${info.frame_size}-byte` : "");
  document.getElementById("stations").appendChild(node);
  const hzEl = node.querySelector(".plot-hz"), pwEl = node.querySelector(".plot-power");
  const cols = [[], ...COLUMNS.map(() => [])];
  const st = {
    info, node, visible: true, dirty: false, cols, marks: [], bands: [], nextMark: 1,
    hzData: [cols[0], cols[1], cols[2]], powerData: [cols[0], cols[3], cols[4]],
    legend: node.querySelector(".st-marks"), bandLegend: node.querySelector(".st-bands"),
    fields: Object.fromEntries([...node.querySelectorAll("[data-f]")].map((el) => [el.dataset.f, el])),
  };
  st.hzPlot = hzPlot(hzEl, st);
  st.powerPlot = powerPlot(pwEl, st);
  hzEl._plot = st.hzPlot; pwEl._plot = st.powerPlot;
  resized.observe(hzEl); resized.observe(pwEl);
  visible.observe(node);
  wireControls(st);
  state.stations.set(info.address, st);
  for (const e of state.early) if (e.station === info.address) markEvent(e, st);
  return st;
}

function phaseBadge(s) {
  if (s.alarm) return ["alarm", "bad"];
  if (!s.connected) return [s.phase ? `P${s.phase}` : "offline", "off"];
  return [`P${s.phase}`, s.phase >= 3 ? "ok" : "warn"];
}

function showStation(st, s, t) {
  const n = st.node;
  n.dataset.phase = String(s.phase);
  n.dataset.outputHz = s.output_hz === null ? "" : String(s.output_hz);
  n.dataset.alarm = s.alarm ? s.alarm.name : "";
  n.dataset.running = String(s.running);
  const [label, cls] = phaseBadge(s);
  const badge = n.querySelector(".st-phase");
  setText(badge, label);
  badge.className = "st-phase badge " + cls;
  const alarm = n.querySelector(".st-alarm");
  const alarmText = s.alarm ? `${s.alarm.name}${s.alarm.code ? " (" + s.alarm.code + ")" : ""}` :
    (s.warnings && s.warnings.length ? "warning: " + s.warnings.join(", ") : "");
  setText(alarm, alarmText);
  alarm.className = "st-alarm" + (!s.alarm && alarmText ? " warning" : "");
  showLeds(n.querySelector(".st-leds"), s.leds || {}, s.led_colors || {});
  const f = st.fields;
  setText(f.run, s.running ? (s.direction === "reverse" ? "REV" : "FWD") : "stop");
  setText(f.reference_hz, fmt(s.reference_hz, 2));
  setText(f.output_hz, fmt(s.output_hz, 2));
  setText(f.output_current_a, fmt(s.output_current_a, 1));
  setText(f.dc_bus_v, fmt(s.dc_bus_v, 0));
  setText(f.motor_speed_rpm, fmt(s.motor_speed_rpm, 0));
  setText(f.rtt, `${fmt(s.rtt_p50_us, 0)} / ${fmt(s.rtt_p99_us, 0)}`);
  setText(f.counts, `${s.missed} / ${s.late}`);
  if (t !== null) pushSample(st, t, s);
}

function showLeds(el, leds, colors) {
  const key = JSON.stringify([leds, colors]);
  if (el._key === key) return;
  el._key = key;
  el.replaceChildren(...Object.entries(leds).map(([name, how]) => {
    const span = document.createElement("span");
    span.className = `led ${how} ${colors[name] || "green"}`;
    span.textContent = name;
    span.title = `${name}: ${how}`;
    return span;
  }));
}

// ---- controls
function wireControls(st) {
  const addr = encodeURIComponent(st.info.name);
  const out = st.node.querySelector(".ctl-result");
  const say = (text, bad) => { out.textContent = text; out.className = "ctl-result" + (bad ? " err" : ""); };
  const form = (cls) => st.node.querySelector(cls);
  const act = async (what, call, describe) => {
    say(what + "…");
    try { say(describe(await call())); } catch (e) { say(`${what}: ${e.message}`, true); }
  };
  const speed = () => Number(form(".ctl-run").elements.speed.value);
  const base = `api/stations/${addr}`;
  const actions = {
    forward: () => act("run", () => api("POST", `${base}/run`, { direction: "forward", hz: speed() }),
      () => `running forward at ${speed()} Hz`),
    reverse: () => act("run", () => api("POST", `${base}/run`, { direction: "reverse", hz: speed() }),
      () => `running in reverse at ${speed()} Hz`),
    stop: () => act("stop", () => api("POST", `${base}/stop`, {}), () => "stopping"),
    "alarm-clear": () => act("alarm clear", () => api("POST", `${base}/alarm-clear`, {}), () => "alarm clear sent"),
    read: () => {
      const name = form(".ctl-param").elements.name.value.trim();
      act("read " + name, () => api("GET", `${base}/params/${encodeURIComponent(name)}`), showParam);
    },
    write: () => {
      const els = form(".ctl-param").elements, name = els.name.value.trim();
      const value = Number(els.value.value);
      act("write " + name, () => api("PUT", `${base}/params/${encodeURIComponent(name)}`,
        { value: Number.isNaN(value) ? els.value.value : value, eeprom: els.eeprom.checked }),
        (r) => "written: " + showParam(r));
    },
    fault: () => {
      const spec = form(".ctl-fault").elements.fault.value.trim();
      act("fault", () => api("POST", `${base}/fault`, { spec: spec }), (r) => `injected ${r.name}: ${r.describe}`);
    },
    impair: () => {
      const spec = form(".ctl-fault").elements.impair.value.trim();
      act("impair", () => api("POST", `${base}/impair`, { spec: spec }),
        (r) => `impaired ${r.name}: ` + (r.describe || JSON.stringify(r.impairment)));
    },
    heal: () => act("heal", () => api("POST", `${base}/heal`, {}),
      (r) => (r.ended ? `healed: ${r.names.join(", ")}` : "nothing to heal")),
  };
  st.node.querySelectorAll("button[data-act]").forEach((b) => b.addEventListener("click", actions[b.dataset.act]));
  st.node.querySelectorAll("form").forEach((f) => f.addEventListener("submit", (ev) => ev.preventDefault()));
}

function showParam(r) {
  const p = r.param;
  const reg = typeof p.register === "number" ? "0x" + p.register.toString(16).toUpperCase().padStart(4, "0") : p.register;
  return `${p.name} = ${p.value}${p.unit ? " " + p.unit : ""} (raw ${p.raw}, register ${reg})`;
}

// ---- the network
function showStatus(s) {
  const t = typeof s.elapsed_s === "number" ? s.elapsed_s : null;
  setText(document.getElementById("elapsed"), t === null ? "bring-up" : `${t.toFixed(1)} s`);
  setText(document.getElementById("step"), s.step || "–");
  setText(document.getElementById("stalls"), describeStalls(s.stalls));
  let worst = null, missed = 0;
  for (const row of s.stations || []) {
    const st = state.stations.get(row.address) || addStation(row);
    showStation(st, row, t);
    if (row.rtt_p99_us !== null && (worst === null || row.rtt_p99_us > worst)) worst = row.rtt_p99_us;
    missed += row.missed || 0;
  }
  if (t !== null) pushRow(state.net, t, [worst, missed], NET_WINDOW_S);
  const now = performance.now();
  if (now - state.lastPlot >= PLOT_EVERY_MS) {
    state.lastPlot = now;
    for (const st of state.stations.values()) if (st.dirty && st.visible) redraw(st);
    state.netPlot.setData(state.net);
  }
}

// the last minute of samples the server kept (its first message on a new stream): the plots start full
function showHistory(h) {
  const at = Object.fromEntries(h.fields.map((f, i) => [f, i]));
  const net = new Map();
  for (const [address, columns] of Object.entries(h.stations)) {
    const st = state.stations.get(address);
    if (!st) continue;
    h.t.forEach((t, i) => {
      pushSample(st, t, Object.fromEntries(COLUMNS.map((k) => [k, columns[at[k]][i]])));
      const rtt = columns[at.rtt_p99_us][i], missed = columns[at.missed][i] || 0;
      const [w, m] = net.get(t) || [null, 0];
      net.set(t, [rtt !== null && (w === null || rtt > w) ? rtt : w, m + missed]);
    });
  }
  for (const [t, [worst, missed]] of [...net].sort((a, b) => a[0] - b[0])) {
    pushRow(state.net, t, [worst, missed], NET_WINDOW_S);
  }
  for (const st of state.stations.values()) redraw(st);
  state.netPlot.setData(state.net);
}

// an event as a numbered mark on its station's plots (every station's, for one on all): actions, checks, alarms
function markKind(e) {
  if (e.kind === "action") return "action";
  if (e.kind === "check") return e.ok ? "check-ok" : "check-fail";
  if (e.kind === "alarm" && !e.cleared) return "alarm";
  return null;
}

// what a mark stands for, without the station its panel names already
function markText(e) {
  if (e.kind === "action") return e.describe || "";
  if (e.kind === "check") return `${e.ok ? "held" : "FAILED"}: ${e.what}${e.detail ? " — " + e.detail : ""}`;
  return `${e.name}${e.code ? " (" + e.code + ")" : ""}`;
}

function markEvent(e, only) {
  const kind = markKind(e);
  if (kind === null || typeof e.at_s !== "number") return;
  const targets = only ? [only] : e.station && e.station !== "all" ? [state.stations.get(e.station)]
    : [...state.stations.values()];
  if (!only && e.station && e.station !== "all" && !targets[0]) { state.early.push(e); return; }
  for (const st of targets) {
    if (!st) continue;
    st.marks.push({ t: e.at_s, n: st.nextMark++, kind, text: markText(e) });
    if (st.marks.length > MAX_MARKS) st.marks.shift();
    st.node.dataset.marks = String(st.nextMark - 1);
    st.dirty = true;
  }
}

function describeStalls(stalls) {
  if (!stalls || typeof stalls !== "object") return "–";
  const count = stalls.count ?? stalls.stalls;
  const longest = stalls.max_ms ?? (typeof stalls.max === "number" ? stalls.max / 1e6 : undefined);
  if (count === undefined) return JSON.stringify(stalls);
  return longest === undefined ? String(count) : `${count} (longest ${Number(longest).toFixed(1)} ms)`;
}

function stationName(key) {
  const st = key ? state.stations.get(key) : null;
  return st ? st.info.name : (key || "");
}

// one line per event kind (mlink_sim/aio/control/events.py); anything else: its fields
function describeEvent(e) {
  const who = stationName(e.station);
  switch (e.kind) {
    case "phase":
      return e.state === "recovered" ? `${who} recovered (${e.reason}, after ${fmt(e.after_s * 1000, 1)} ms)`
        : `${who} ${e.was} → ${e.state}` + (e.phase !== undefined ? ` (P${e.phase})` : "");
    case "alarm":
      return e.cleared ? `${who} alarm cleared` : `${who} ${e.name}${e.code ? " (" + e.code + ")" : ""}`;
    case "check":
      return `${e.ok ? "held" : "FAILED"}: ${e.what}${e.detail ? " — " + e.detail : ""}`;
    default: {
      if (e.describe) return [who, e.describe].filter(Boolean).join(" ");
      const rest = Object.entries(e).filter(([k]) => !["seq", "at_s", "kind", "station"].includes(k));
      return [who, rest.map(([k, v]) => `${k} ${typeof v === "object" ? JSON.stringify(v) : v}`).join(", ")]
        .filter(Boolean).join(" ");
    }
  }
}

function showEvent(e) {
  markEvent(e);
  const list = document.getElementById("events");
  const li = document.createElement("li");
  li.dataset.kind = e.kind;
  const t = document.createElement("span"); t.className = "t"; t.textContent = fmt(e.at_s, 2) + " s";
  if (e.at_s < 0) {  // before the timeline's 0 s: its time counts up to the end of bring-up
    const why = document.createElement("span");
    why.className = "before-zero";
    why.textContent = state.vocab.before_zero;
    why.title = "before the timeline's 0 s (the end of bring-up): the stations were being brought up";
    t.append(" ", why);
  }
  const k = document.createElement("span"); k.className = "k k-" + e.kind; k.textContent = e.kind;
  if (e.kind === "check") k.classList.add(e.ok ? "ok" : "bad");
  li.append(t, k, document.createTextNode(describeEvent(e)));
  list.prepend(li);
  while (list.children.length > MAX_EVENTS) list.lastElementChild.remove();
}

// ---- the event stream (fetch, so that it carries the token; EventSource cannot send a header)
async function stream() {
  for (;;) {
    try {
      const r = await fetch("api/events", { headers: headers(false), cache: "no-store" });
      if (r.status === 401) { askToken(); return; }
      if (!r.ok) throw new Error(String(r.status));
      setLink("live", "ok");
      const reader = r.body.pipeThrough(new TextDecoderStream()).getReader();
      let buf = "";
      for (;;) {
        const { value, done } = await reader.read();
        if (done) break;
        buf += value;
        let cut;
        while ((cut = buf.indexOf("\n\n")) >= 0) {
          message(buf.slice(0, cut));
          buf = buf.slice(cut + 2);
        }
      }
    } catch (e) { /* reconnect below */ }
    setLink("reconnecting…", "warn");
    await new Promise((done) => setTimeout(done, 1000));
  }
}

function message(block) {
  let name = "message", data = "";
  for (const line of block.split("\n")) {
    if (line.startsWith("event:")) name = line.slice(6).trim();
    else if (line.startsWith("data:")) data += line.slice(5).trim();
  }
  if (!data) return;
  const body = JSON.parse(data);
  if (name === "status") { setLink("live", "ok"); showStatus(body); }
  else if (name === "history") showHistory(body);
  else if (name === "event") showEvent(body);
  else if (name === "error") setLink("network not answering", "bad");
}

async function start() {
  try {
    if (state.vocab === null) {
      const r = await fetch("plots.json", { cache: "no-store" });
      state.vocab = await r.json();
      state.net = [[], [], []];
      const netEl = document.getElementById("net-plot");
      state.netPlot = netPlot(netEl);
      netEl._plot = state.netPlot;
      resized.observe(netEl);
    }
    const net = await api("GET", "api/network");
    document.title = `${net.name} – mlink-sim`;
    setText(document.getElementById("net-name"), net.name);
    setText(document.getElementById("net-cycle"), `${net.stations.length} stations, ${net.cycle} cycle`);
    for (const info of net.stations) if (!state.stations.has(info.address)) addStation(info);
    if (net.stations.length <= 8) document.querySelectorAll(".controls").forEach((d) => { d.open = true; });
  } catch (e) {
    if (e instanceof ApiError && !document.getElementById("token-form").hidden) return;
    setLink("network not answering", "bad");
  }
  stream();
}

start();
