// mlink-sim's live page (docs/web.md): reads GET api/network once, then the event stream api/events (status at
// most ten times a second, the network's events as they happen); the controls call the API. No build step, no
// framework: the plots are uPlot (static/vendor/uplot).
"use strict";

const WINDOW_S = 60;            // the stations' plots: the last minute
const NET_WINDOW_S = 600;       // the network's plot: the last ten minutes
const PLOT_EVERY_MS = 250;      // plots are redrawn at most four times a second (and only those in view)
const MAX_EVENTS = 300;

const state = { token: null, stations: new Map(), net: null, netPlot: null, lastPlot: 0 };

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

// ---- plots
const compact = (u, vals) => vals.map((v) => (v === null ? "" : Math.abs(v) >= 10000 ? `${v / 1000}k` : String(v)));

function plotOptions(el, series, axes) {
  return {
    width: Math.max(200, el.clientWidth || 300), height: 130,
    cursor: { drag: { x: false, y: false } },
    legend: { live: false },
    scales: { x: { time: false } },
    series: [{ label: "t s" }, ...series],
    axes: [{ size: 28, values: (u, vals) => vals.map((v) => v.toFixed(0)) },
      ...axes.map((a) => ({ values: compact, ...a }))],
  };
}

function hzPlot(el) {
  return new uPlot(plotOptions(el, [
    { label: "ref Hz", scale: "hz", stroke: "#8c959f", dash: [5, 4], width: 1.5 },
    { label: "output Hz", scale: "hz", stroke: "#1f6feb", width: 2 },
  ], [{ scale: "hz", size: 42 }]), [[], [], []], el);
}

function powerPlot(el) {
  return new uPlot(plotOptions(el, [
    { label: "current A", scale: "A", stroke: "#d97706", width: 1.5 },
    { label: "DC bus V", scale: "V", stroke: "#7c3aed", width: 1.5 },
  ], [{ scale: "A", size: 42 }, { scale: "V", side: 1, size: 46, grid: { show: false } }]), [[], [], []], el);
}

function netPlot(el) {
  return new uPlot(plotOptions(el, [
    { label: "RTT p99 µs", scale: "us", stroke: "#1f6feb", width: 1.5 },
    { label: "missed", scale: "n", stroke: "#cf222e", width: 1.5 },
  ], [{ scale: "us", size: 46 }, { scale: "n", side: 1, size: 42, grid: { show: false } }]), [[], [], []], el);
}

function push(cols, t, values, windowS) {
  cols[0].push(t);
  values.forEach((v, i) => cols[i + 1].push(v === undefined ? null : v));
  let cut = 0;
  while (cut < cols[0].length && cols[0][cut] < t - windowS) cut++;
  if (cut) cols.forEach((c) => c.splice(0, cut));
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
    if (plot) plot.setSize({ width: Math.max(200, e.contentRect.width), height: 130 });
  }
});

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
  const st = {
    info, node, visible: true, dirty: false,
    hz: [[], [], []], power: [[], [], []],
    hzPlot: hzPlot(hzEl), powerPlot: powerPlot(pwEl),
    fields: Object.fromEntries([...node.querySelectorAll("[data-f]")].map((el) => [el.dataset.f, el])),
  };
  hzEl._plot = st.hzPlot; pwEl._plot = st.powerPlot;
  resized.observe(hzEl); resized.observe(pwEl);
  visible.observe(node);
  wireControls(st);
  state.stations.set(info.address, st);
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
  if (t !== null) {
    push(st.hz, t, [s.reference_hz, s.output_hz], WINDOW_S);
    push(st.power, t, [s.output_current_a, s.dc_bus_v], WINDOW_S);
    st.dirty = true;
  }
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
      act("fault", () => api("POST", `${base}/fault`, { spec: spec }), (r) => "injected: " + r.describe);
    },
    impair: () => {
      const spec = form(".ctl-fault").elements.impair.value.trim();
      act("impair", () => api("POST", `${base}/impair`, { spec: spec }),
        (r) => "impaired: " + (r.describe || JSON.stringify(r.impairment)));
    },
    heal: () => act("heal", () => api("POST", `${base}/heal`, {}), (r) => `healed (${r.ended} ended)`),
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
  if (t !== null) push(state.net, t, [worst, missed], NET_WINDOW_S);
  const now = performance.now();
  if (now - state.lastPlot >= PLOT_EVERY_MS) {
    state.lastPlot = now;
    for (const st of state.stations.values()) {
      if (st.dirty && st.visible) {
        st.hzPlot.setData(st.hz);
        st.powerPlot.setData(st.power);
        st.dirty = false;
      }
    }
    state.netPlot.setData(state.net);
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
  const list = document.getElementById("events");
  const li = document.createElement("li");
  li.dataset.kind = e.kind;
  const t = document.createElement("span"); t.className = "t"; t.textContent = fmt(e.at_s, 2) + " s";
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
  else if (name === "event") showEvent(body);
  else if (name === "error") setLink("network not answering", "bad");
}

async function start() {
  try {
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

state.net = [[], [], []];
const netEl = document.getElementById("net-plot");
state.netPlot = netPlot(netEl);
netEl._plot = state.netPlot;
resized.observe(netEl);
start();
