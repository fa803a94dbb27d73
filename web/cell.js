// The cell page (docs/web-dashboard.md, "The cell page"): one row per machine on the shop's MQTT
// broker, from what each `ncd serve` publishes (docs/fleet-mqtt.md, "Topics"). The browser talks
// to mosquitto itself over MQTT on WebSockets (mqtt-ws.js); no server of ours is in between, and
// the broker's ACL decides what this page's user may read. How it works:
//
// - A machine is a topic root: the topic without its last level ("ncd/cell1/m1/" of
//   "ncd/cell1/m1/status"). The page subscribes to online, state, status and events for roots of
//   one and two levels under the prefix (ncd/<host>/ and ncd/<cell>/<machine>/), and never to
//   cmd or reply. A row appears with the first message of a root.
// - The state shown is the newest one by the time in the message (time_unix_s): the retained
//   state topic (on connecting and on change), the status (status_hz times a second) and the
//   service's state events (emitted at the transition itself), whichever arrives first. An older
//   one arriving later (a retained state after a reconnection) changes nothing.
// - Freshness: a machine is "stale" when no status came for 5 of its status periods (at least
//   3 s; the period is the online message's status_hz), and "offline" when its online topic says
//   false (its last will, published by the broker when the machine's connection died, or its
//   own on a clean stop). While the broker is away every machine goes stale; after the page
//   reconnects (with back-off, mqtt-ws.js) the retained online and state come back at once and
//   the statuses within one period.
// - Alarms: the status's job_error and live-limit violations, and the alarm and violation events
//   of the current job (cleared when a job starts).
// - For measurements the page keeps window.cell.log: each state a machine's row shows as of a
//   message (a change, or the same state confirmed by a newer message) with the message's time
//   and the wall clock (Date.now()) just after the DOM was written, and the count of messages
//   received (bounded: the last 50000 entries).
"use strict";

const kMaxLog = 50000;
const kMinStaleMs = 3000;
const kStalePeriods = 5;

const params = new URLSearchParams(location.search);
const defaults = {
  broker: params.get("broker") || "ws://" + (location.hostname || "127.0.0.1") + ":9001/",
  user: params.get("user") || "web",
  prefix: params.get("prefix") || "ncd/",
};
const $ = (id) => document.getElementById(id);
const machines = new Map(); // topic root → machine
let client = null;
let connectedAtMs = Date.now();
let summaryDue = false;

window.cell = { log: { displays: [], received: 0, invalid: 0 }, machines };

function text(el, value) {
  const s = String(value);
  if (el.textContent !== s) el.textContent = s;
}

function fixed(v, digits) {
  return typeof v === "number" && isFinite(v) ? v.toFixed(digits) : "-";
}

// A link to follow only if it is http(s): a publisher cannot make the page run a script.
function safeUrl(url) {
  return typeof url === "string" && /^https?:\/\/[^\s"<>]+$/.test(url) ? url : null;
}

function newMachine(root) {
  const tr = document.createElement("tr");
  tr.dataset.root = root;
  const cells = {};
  for (const name of ["name", "state", "job", "progress", "feed", "override", "alarms", "fresh"]) {
    cells[name] = document.createElement("td");
    cells[name].className = name;
    tr.appendChild(cells[name]);
  }
  const link = document.createElement("a");
  link.textContent = root;
  cells.name.appendChild(link);
  const badge = document.createElement("span");
  badge.className = "badge state";
  badge.textContent = "-";
  cells.state.appendChild(badge);
  const bar = document.createElement("progress");
  bar.max = 1;
  bar.value = 0;
  const pct = document.createElement("span");
  cells.progress.append(bar, " ", pct);
  const m = {
    root, tr, cells, link, badge, bar, pct,
    state: null, stateT: -Infinity, online: null, statusHz: null,
    lastStatusMs: connectedAtMs, lastSeq: 0, eventAlarms: [], statusAlarms: [],
  };
  // Rows in the order of their roots.
  const after = [...machines.keys()].filter((r) => r > root).sort()[0];
  $("rows").insertBefore(tr, after ? machines.get(after).tr : null);
  machines.set(root, m);
  $("empty").hidden = true;
  return m;
}

function showState(m, state, timeS, source) {
  if (typeof state !== "string") return;
  const t = typeof timeS === "number" ? timeS : -Infinity;
  if (t < m.stateT) return;
  m.stateT = t;
  if (state !== m.state) {
    m.state = state;
    text(m.badge, state);
    m.badge.className = "badge state " + state;
  }
  // Every state the DOM shows as of a message time (changed or confirmed), for the latency.
  const log = window.cell.log.displays;
  log.push({ machine: m.root, state, source, msg_time_s: timeS, shown_ms: Date.now() });
  if (log.length > kMaxLog) log.splice(0, log.length - kMaxLog);
}

// The job's file name; its whole path on hover.
function showJob(m, job) {
  const path = typeof job === "string" && job ? job : "-";
  text(m.cells.job, path.slice(path.lastIndexOf("/") + 1));
  if (m.cells.job.title !== path) m.cells.job.title = path;
}

// Each alarm once (the status's job_error is also the alarm event's text); the whole text on
// hover, the first kAlarmChars shown.
const kAlarmChars = 160;
function showAlarms(m) {
  const all = [...new Set([...m.statusAlarms, ...m.eventAlarms])].join(" · ");
  text(m.cells.alarms, all.length > kAlarmChars ? all.slice(0, kAlarmChars) + "…" : all);
  if (m.cells.alarms.title !== all) m.cells.alarms.title = all;
}

function onOnline(m, p) {
  m.online = p.online === true;
  if (typeof p.status_hz === "number" && p.status_hz > 0) m.statusHz = p.status_hz;
  if (m.online && p.time_unix_s !== m.onlineT) {
    m.onlineT = p.time_unix_s;
    m.lastSeq = 0; // a restarted service counts its events from 1 again
  }
  const url = safeUrl(p.page_url);
  if (url) m.link.href = url;
  else if (m.online) m.link.removeAttribute("href");
  refreshFreshness(m, Date.now());
}

function onStatus(m, p) {
  m.lastStatusMs = Date.now();
  if (m.online === false) m.online = true; // a status is proof of life
  showState(m, p.state, p.time_unix_s, "status");
  showJob(m, p.job);
  const progress = typeof p.progress === "number" ? p.progress : 0;
  if (m.bar.value !== progress) m.bar.value = progress;
  text(m.pct, fixed(progress * 100, 0) + " %");
  const limit = p.feed_limit_mm_per_min;
  text(m.cells.feed, fixed(p.feed_mm_per_min, 1) + (typeof limit === "number" ? " of " + fixed(limit * (p.override_percent || 100) / 100, 1) : ""));
  text(m.cells.override, fixed(p.override_percent, 0) + " %");
  const alarms = [];
  if (typeof p.job_error === "string" && p.job_error) alarms.push(p.job_error);
  const v = p.live_limit_violations;
  if (v && typeof v === "object") {
    const n = ["feed", "accel", "jerk", "chord"].reduce((a, k) => a + (Number(v[k]) || 0), 0);
    if (n > 0) alarms.push(n + " live limit violation" + (n === 1 ? "" : "s"));
  }
  if (p.stream && Number(p.stream.link_losses) > 0) alarms.push("link lost " + p.stream.link_losses + "×");
  m.statusAlarms = alarms;
  showAlarms(m);
  refreshFreshness(m, m.lastStatusMs);
}

function onEvent(m, p) {
  if (typeof p.seq === "number") {
    if (p.seq <= m.lastSeq) return; // QoS 1 may deliver an event twice
    m.lastSeq = p.seq;
  }
  if (p.kind === "state") showState(m, p.state, p.time_unix_s, "event");
  if (p.kind === "job" && typeof p.text === "string" && p.text.startsWith("started")) {
    m.eventAlarms = [];
  }
  if (p.kind === "alarm" || p.kind === "violation") {
    m.eventAlarms.push(String(p.text));
    if (m.eventAlarms.length > 3) m.eventAlarms.shift();
  }
  showAlarms(m);
}

function onMessage(topic, payload) {
  ++window.cell.log.received;
  const cut = topic.lastIndexOf("/");
  const root = topic.slice(0, cut + 1);
  const kind = topic.slice(cut + 1);
  let p;
  try {
    p = JSON.parse(payload);
  } catch (e) {
    ++window.cell.log.invalid;
    return;
  }
  if (p === null || typeof p !== "object") return void ++window.cell.log.invalid;
  const m = machines.get(root) || newMachine(root);
  if (kind === "online") onOnline(m, p);
  else if (kind === "state") {
    showState(m, p.state, p.time_unix_s, "state");
    if (typeof p.job === "string") showJob(m, p.job);
  } else if (kind === "status") onStatus(m, p);
  else if (kind === "events") onEvent(m, p);
}

function refreshFreshness(m, now) {
  const periodMs = m.statusHz ? 1000 / m.statusHz : 1000;
  const staleMs = Math.max(kMinStaleMs, kStalePeriods * periodMs);
  const ageS = (now - m.lastStatusMs) / 1000;
  let cls = "", label;
  if (m.online === false) {
    cls = "offline";
    label = "offline";
  } else if (now - m.lastStatusMs > staleMs) {
    cls = "stale";
    label = "stale: no status for " + ageS.toFixed(0) + " s";
  } else {
    label = ageS < 1.5 ? "now" : ageS.toFixed(0) + " s ago";
  }
  if (m.tr.className !== cls) {
    m.tr.className = cls;
    summaryDue = true;
  }
  text(m.cells.fresh, label);
}

function summarize() {
  const now = Date.now();
  for (const m of machines.values()) refreshFreshness(m, now);
  summaryDue = false;
  const counts = {};
  for (const m of machines.values()) {
    const key = m.tr.className || m.state || "?";
    counts[key] = (counts[key] || 0) + 1;
  }
  const parts = Object.keys(counts).sort().map((k) => counts[k] + " " + k);
  text($("summary"), machines.size + " machines" + (parts.length ? ": " + parts.join(", ") : ""));
}

function onState(state, detail) {
  const badge = $("broker-state");
  const words = { connecting: "connecting", connected: "connected", waiting: "broker lost", stopped: "not connected" };
  text(badge, words[state] || state);
  badge.className = "badge " + state;
  text($("broker-detail"), detail);
  if (state === "connected") connectedAtMs = Date.now();
}

function prefixFilters(prefix) {
  const p = prefix.endsWith("/") ? prefix : prefix + "/";
  const out = [];
  for (const level of ["+/", "+/+/"]) {
    out.push([p + level + "online", 1], [p + level + "state", 1], [p + level + "status", 0],
             [p + level + "events", 1]);
  }
  return out;
}

function connect() {
  if (client) client.stop();
  const password = $("password").value;
  sessionStorage.setItem("ncd-cell", JSON.stringify({
    broker: $("broker-url").value, user: $("user").value, prefix: $("prefix").value, password,
  }));
  client = new MqttWsClient({
    url: $("broker-url").value.trim(),
    username: $("user").value.trim(),
    password,
    subscriptions: prefixFilters($("prefix").value.trim() || "ncd/"),
    onMessage,
    onState,
  });
  window.cell.client = client;
  client.start();
}

function init() {
  let saved = {};
  try {
    saved = JSON.parse(sessionStorage.getItem("ncd-cell") || "{}") || {};
  } catch (e) {
    saved = {};
  }
  $("broker-url").value = params.get("broker") || saved.broker || defaults.broker;
  $("user").value = params.get("user") || saved.user || defaults.user;
  $("prefix").value = params.get("prefix") || saved.prefix || defaults.prefix;
  $("password").value = saved.password || "";
  $("login").addEventListener("submit", (ev) => {
    ev.preventDefault();
    connect();
  });
  setInterval(summarize, 500);
  setInterval(() => summaryDue && summarize(), 100);
  if (saved.password !== undefined) connect(); // this tab connected before: again after a reload
}

init();
