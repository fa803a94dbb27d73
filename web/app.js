// The ncd dashboard (docs/web-dashboard.md). One WebSocket to /ws: requests are the control
// socket's (with the token when one is typed), replies arrive in order as {"reply": …}, status
// snapshots as {"status": …}, the programmed path of a submitted job as {"program": …}, the
// service's events as {"event": …} (the last few listed on the page).
'use strict';

const $ = (id) => document.getElementById(id);
const tokenInput = $('token');
tokenInput.value = localStorage.getItem('ncd-token') || '';
tokenInput.addEventListener('change', () => {
  localStorage.setItem('ncd-token', tokenInput.value);
  request({ cmd: 'status' });
});

let ws = null;
const pending = [];  // reply callbacks, oldest first
let program = null;  // {job, points: [[x,y,z]…], programmed_feed_max_mm_per_min}
let trace = [];      // positions of the current job
let traceJob = null;
let feedHistory = [];  // {t_s, feed, limit} of the last minute (browser clock)
let lastStatus = null;
const kTraceMax = 50000;
const kFeedWindowS = 60;

function connect() {
  const scheme = location.protocol === 'https:' ? 'wss' : 'ws';
  ws = new WebSocket(`${scheme}://${location.host}/ws`);
  ws.onopen = () => {
    setConn('connected', true);
    request({ cmd: 'status' });  // with a token, this lets status flow
  };
  ws.onclose = () => {
    setConn('disconnected', false);
    enableControls(null);
    while (pending.length) pending.shift()({ ok: false, error: 'the connection closed' });
    setTimeout(connect, 1000);
  };
  ws.onmessage = (event) => {
    let m;
    try { m = JSON.parse(event.data); } catch (e) { return; }
    if (m.reply) {
      const cb = pending.shift();
      if (cb) cb(m.reply);
    } else if (m.status) {
      showStatus(m.status);
    } else if (m.program) {
      program = m.program;
      showListing(program);
      draw();
    } else if (m.event) {
      showEvent(m.event);
    }
  };
}

// One of the service's events, at the top of the list of the last kEventsShown; an alarm
// (the job's alarm, a live limit's violation, a link event that names an alarm, an error or a
// loss) also in the alarms panel, which a new submit clears as the service clears the job's
// error.
const kEventsShown = 12;
let alarms = [];
function noteAlarm(e) {
  if (e.kind === 'job' && (e.text || '').startsWith('submitted')) alarms = [];
  const linkAlarm = e.kind === 'link' && /alarm|error|lost|gave up|given up/i.test(e.text || '');
  if (e.kind === 'alarm' || e.kind === 'violation' || linkAlarm) alarms.push(e);
  const list = $('alarms');
  list.replaceChildren(...alarms.slice(-kEventsShown).reverse().map((a) => {
    const li = document.createElement('li');
    li.textContent = `${eventTime(a)} · ${a.kind} · ${a.text || ''}`;
    return li;
  }));
  $('alarms-none').textContent = alarms.length ? '' : 'none';
}

function showEvent(e) {
  noteAlarm(e);
  const li = document.createElement('li');
  li.className = 'event ' + (e.kind || '');
  const holder = e.holder && e.holder !== 'none' ? ' by the ' + e.holder : '';
  li.textContent = `${eventTime(e)} · ${e.kind} · ${e.state}${holder} · ${e.text || ''}`;
  const list = $('events');
  list.insertBefore(li, list.firstChild);
  while (list.children.length > kEventsShown) list.removeChild(list.lastChild);
}

// "12:03:41 · 4.216 s": the wall clock of the event (the browser's time zone) and the job's
// motion time; the motion time only once a job has started (none for idle, ready).
function eventTime(e) {
  const wall = typeof e.time_unix_s === 'number'
    ? new Date(e.time_unix_s * 1000).toLocaleTimeString('en-GB', { hour12: false }) : '-';
  if (e.state === 'idle' || e.state === 'ready') return wall;
  return `${wall} · ${fixed(e.job_t_s, 3)} s`;
}

function setConn(text, ok) {
  $('conn').textContent = text;
  $('conn').style.background = ok ? '#059669' : '#dc2626';
}

// Sends one request; shows and returns (through the promise) its reply.
function request(req) {
  if (tokenInput.value) req.token = tokenInput.value;
  return new Promise((resolve) => {
    if (!ws || ws.readyState !== WebSocket.OPEN) {
      resolve({ ok: false, error: 'not connected' });
      return;
    }
    pending.push((reply) => {
      if (req.cmd !== 'status') {
        $('message').textContent = reply.ok
          ? `${req.cmd}: ok${reply.state ? ' (' + reply.state + ')' : ''}${reply.warning ? ' — ' + reply.warning : ''}`
          : `${req.cmd}: ${reply.error}`;
        $('message').className = reply.ok ? 'message' : 'message error';
      }
      resolve(reply);
    });
    ws.send(JSON.stringify(req));
  });
}

const fixed = (v, n) => (typeof v === 'number' && isFinite(v) ? v.toFixed(n) : '-');

function showStatus(s) {
  lastStatus = s;
  const state = s.state || '-';
  $('state').textContent = state;
  $('state').className = 'badge state ' + state;
  $('job').textContent = s.job ?? '-';
  // The header's line: the listing's (the controller's where it reports it, else ncd's).
  const at = executingLine(s);
  $('line').textContent = at ? at.line : '-';
  const p = s.position;
  showDro(s);
  showMachineState(s);
  markListing(s);
  $('pos-x').textContent = p ? fixed(p[0], 3) : '-';
  $('pos-y').textContent = p ? fixed(p[1], 3) : '-';
  $('pos-z').textContent = p ? fixed(p[2], 3) : '-';
  $('feed').textContent = fixed(s.feed_mm_per_min, 1);
  const limit = feedLimit(s);
  $('feed-limit').textContent = limit !== null ? fixed(limit, 1) : '-';
  $('feed-limit-note').textContent = typeof s.feed_limit_mm_per_min === 'number'
    ? `(the limit ${fixed(s.feed_limit_mm_per_min, 1)} × override` +
      (s.binding_limit ? ' · binding: ' + s.binding_limit : '') + ')'
    : '';
  $('override').textContent = fixed(s.override_percent, 0);
  showOverrideSlider(s.override_percent);
  enableControls(s);
  $('progress').textContent = typeof s.progress === 'number' ? (100 * s.progress).toFixed(1) + ' %' : '-';
  $('progress-bar').value = s.progress || 0;
  $('time-left').textContent = typeof s.time_left_s === 'number' ? formatDuration(s.time_left_s) : '-';
  $('overruns').textContent = s.overruns ?? '-';
  $('late').textContent = s.late_wakeups ?? '-';
  drawLateness(s.lateness_histogram || []);
  $('error').textContent = s.job_error || '';
  showLink(s.stream);
  // The trace: a new job (or a restart of it) begins a new one.
  if (s.job !== traceJob || (state === 'ready' && trace.length)) {
    trace = [];
    traceJob = s.job;
  }
  if (p && (state === 'running' || state === 'holding' || state === 'streaming' || state === 'done' || state === 'stopped')) {
    const last = trace[trace.length - 1];
    if (!last || last[0] !== p[0] || last[1] !== p[1] || last[2] !== p[2]) {
      trace.push(p);
      if (trace.length > kTraceMax) trace.splice(0, trace.length - kTraceMax);
    }
  }
  const now = performance.now() / 1000;
  feedHistory.push({ t: now, feed: s.feed_mm_per_min || 0, limit });
  while (feedHistory.length && feedHistory[0].t < now - kFeedWindowS) feedHistory.shift();
  draw();
}

// The DRO (docs/web-dashboard.md, "The DRO"): the status's dro, in the program's units, work
// and machine coordinates, the tool length offset and the work offset apart, and its source:
// the controller's status report, or ncd's commanded position (which runs ahead of it).
function showDro(s) {
  const d = s.dro;
  const places = d && d.units === 'inch' ? 4 : 3;
  const axes = ['x', 'y', 'z'];
  axes.forEach((a, k) => {
    $('dro-w' + a).textContent = d ? fixed(d.work[k], places) : '-';
    $('dro-m' + a).textContent = d ? fixed(d.machine[k], places) : '-';
  });
  $('dro-units').textContent = d ? d.units : '-';
  $('dro-source').textContent = !d ? '-' : d.source === 'controller'
    ? `from the controller's report, ${fixed(d.age_s, 2)} s old`
    : 'commanded by ncd' + (s.stream ? ' (ahead of the controller)' : '');
  const xyz = (v) => v ? `X${fixed(v[0], places)} Y${fixed(v[1], places)} Z${fixed(v[2], places)}` : '-';
  const c = s.commanded_state;
  $('dro-tlo').textContent = d
    ? `${xyz(d.tool_length)} ${d.units}` + (c && c.tool_length_h !== null ? ` (G43 H${c.tool_length_h})` : '') : '-';
  $('dro-offset').textContent = d ? `${xyz(d.work_offset)} ${d.units}` : '-';
  $('dro-note').textContent = d && !d.modal_known
    ? 'the program\'s offsets are not known here: work = machine' : (d && d.note) || '';
  const q = s.controller_progress;
  $('behind').textContent = q
    ? `${q.blocks_behind} blocks, ${fixed(q.seconds_behind, 2)} s` +
      (q.source === 'last sent' ? ' at least (drip: from the blocks the line has carried)' : ` (${q.source})`)
    : '-';
}

// Spindle, coolant, tool: the program's state where the controller is (ack, from its line) or
// where ncd commands (drip, a job without a link); the controller's own state and report.
function showMachineState(s) {
  const c = s.commanded_state;
  const r = s.controller;
  $('state-source').textContent = c ? `the program's, at line ${c.line ?? '-'} (commanded)` : '-';
  const dir = { cw: 'clockwise (M3)', ccw: 'counter-clockwise (M4)', off: 'off (M5)' };
  $('spindle').textContent = c
    ? `${dir[c.spindle] || c.spindle}, S${fixed(c.spindle_rpm, 0)} rpm` +
      (r && typeof r.spindle_rpm === 'number' ? ` · controller ${fixed(r.spindle_rpm, 0)} rpm` : '')
    : '-';
  $('coolant').textContent = c
    ? [c.coolant.mist ? 'mist (M7)' : '', c.coolant.flood ? 'flood (M8)' : ''].filter((x) => x).join(', ') || 'off (M9)'
    : '-';
  $('tool').textContent = c
    ? `T${c.tool} · length offset ${fixed(c.tool_length_mm[2], 3)} mm` +
      (c.tool_length_h !== null ? ` (H${c.tool_length_h})` : '') +
      ` · work offset ${c.work_offset_mm.map((v) => fixed(v, 3)).join(' ')} mm`
    : '-';
  $('ctl-state').textContent = r ? r.state : (s.stream ? 'not reported (drip feed)' : '-');
  $('ctl-state').className = r && /^Alarm/.test(r.state) ? 'error' : '';
  $('ctl-report').textContent = r
    ? [r.mpos_mm ? `MPos ${r.mpos_mm.map((v) => fixed(v, 3)).join(',')}` : '',
       r.wpos_mm ? `WPos ${r.wpos_mm.map((v) => fixed(v, 3)).join(',')}` : '',
       r.free_blocks !== null ? `Bf ${r.free_blocks},${r.free_bytes}` : '',
       r.line_number !== null ? `Ln ${r.line_number}` : '',
       r.feed_mm_per_min !== null ? `F ${fixed(r.feed_mm_per_min, 0)}` : '',
       `${fixed(r.age_s, 2)} s old`].filter((x) => x).join(' · ')
    : '-';
}

// The listing (docs/web-dashboard.md, "The listing"): the program's lines, the executing one
// marked and scrolled to: the controller's line where its report gives it (Ln:, or the blocks
// it executed), else the last sent (drip), else ncd's commanded line; labelled with its source.
let listingMarked = null;
function showListing(prog) {
  const list = $('listing');
  listingMarked = null;
  const lines = prog && prog.listing ? prog.listing : [];
  list.replaceChildren(...lines.map((text) => {
    const li = document.createElement('li');
    li.textContent = text;
    return li;
  }));
  $('listing-line').textContent = prog && !prog.listing ? 'no program text (a generated or JSON path)' : '-';
}

function executingLine(s) {
  const q = s.controller_progress;
  if (q && q.line) {
    return { line: q.line, source: q.source === 'last sent' ? 'last sent (drip: the controller does not report its line)' : 'executing, ' + q.source };
  }
  // The move's own line (commanded_state), else the path segment's.
  const c = s.commanded_state;
  const line = (c && c.line) || s.line || (s.stopped && s.stopped.line);
  return typeof line === 'number' ? { line, source: 'commanded by ncd' } : null;
}

function markListing(s) {
  const list = $('listing');
  const at = program && program.job === s.job ? executingLine(s) : null;
  if (!program || !program.listing) return;
  $('listing-line').textContent = at ? `line ${at.line} · ${at.source}` : '-';
  const li = at ? list.children[at.line - 1] : null;
  if (li === listingMarked) return;
  if (listingMarked) listingMarked.classList.remove('exec');
  listingMarked = li || null;
  if (!li) return;
  li.classList.add('exec');
  list.scrollTop = li.offsetTop - list.clientHeight / 2;
}

// The slider shows the service's override (every status, so also on load), except while the
// operator moves it: until Set, or 10 s after the last move without Set (it then shows the
// service's again).
const kOverrideEditS = 10;
let overrideEditing = false;
let overrideEditTimer = null;
function showOverrideSlider(percent) {
  if (overrideEditing || typeof percent !== 'number') return;
  $('override-input').value = String(percent);
  $('override-value').textContent = fixed(percent, 0);
}

// Each control enabled only where the service takes it (docs/web-dashboard.md, "The controls").
function enableControls(s) {
  const state = s ? s.state : null;
  const held = state === 'holding' && s.holder === 'operator';
  const busy = state === 'running' || state === 'holding' || state === 'streaming';
  const on = {
    'start': state === 'ready',
    'cycle-start': state === 'ready' || held,
    'hold': state === 'running',
    'resume': held,
    'stop': state === 'running' || state === 'holding',
    'submit-file': state !== null && !busy,
    'submit-chamfer': state !== null && !busy,
    'override-set': state !== null && state !== 'streaming',
  };
  for (const [id, enabled] of Object.entries(on)) $(id).disabled = !enabled;
}

// The feed's ceiling at the tool: the feed laws' limit there (the status's
// feed_limit_mm_per_min, at 100 %) times the override; null before the first setpoint
// (docs/web-dashboard.md).
function feedLimit(s) {
  if (typeof s.feed_limit_mm_per_min !== 'number') return null;
  return s.feed_limit_mm_per_min * (s.override_percent ?? 100) / 100;
}

function formatDuration(t) {
  const m = Math.floor(t / 60);
  const s = t - 60 * m;
  return m > 0 ? `${m} min ${s.toFixed(0)} s` : `${s.toFixed(1)} s`;
}

function showLink(l) {
  $('link-port').textContent = l ? `${l.port} (${l.settings})` : 'no streaming';
  $('link-blocks').textContent = l ? l.blocks_encoded : '-';
  $('link-waiting').textContent = l ? l.blocks_waiting : '-';
  $('link-chars').textContent = l ? l.chars_encoded : '-';
  $('link-held').textContent = l ? (l.held_by_link ? 'yes' : 'no') : '-';
  $('link-event').textContent = l ? l.last_event || '-' : '-';
  // The sender's live counters (docs/web-dashboard.md, "The link").
  $('link-bytes').textContent = l ? l.bytes_written : '-';
  $('link-written').textContent = l ? l.blocks_written : '-';
  $('link-acked').textContent = l && l.blocks_acked !== null ? l.blocks_acked : '-';
  $('link-xoff').textContent = l ? `${l.xoff_count}${l.xoff_held ? ' (holding now)' : ''}` : '-';
  $('link-buffer').textContent = l
    ? `${l.controller_buffer_bytes} of ${l.controller_buffer_limit_bytes} (${l.controller_buffer_basis})` : '-';
  $('link-underruns').textContent = l ? l.underruns : '-';
  $('link-reconnects').textContent = l ? `${l.reconnects} · lost ${l.link_losses}` : '-';
  $('link-end').textContent = l && l.done
    ? (l.completed ? 'completed' : 'not completed: ' + (l.failure || '')) +
      ` · ${fixed(100 * l.link_use, 0)} % of the line` : '-';
}

// The status's lateness histogram ([{from_us, to_us, count}], non-empty bins): one bar per bin
// from the first to the last non-empty one, heights linear in the count, µs on a log axis.
function drawLateness(bins) {
  const canvas = $('lateplot');
  if (!canvas) return;
  const g = canvas.getContext('2d');
  g.clearRect(0, 0, canvas.width, canvas.height);
  if (!bins.length) return;
  const total = bins.reduce((n, b) => n + b.count, 0);
  const most = Math.max(...bins.map((b) => b.count));
  const lo = Math.log10(Math.max(bins[0].from_us, 1e-3));
  const hi = Math.log10(bins[bins.length - 1].to_us);
  const margin = 24;
  const X = (us) => margin + (Math.log10(Math.max(us, 1e-3)) - lo) / Math.max(hi - lo, 1e-9) *
    (canvas.width - 2 * margin);
  g.fillStyle = '#2563eb';
  for (const b of bins) {
    const h = (canvas.height - 2 * margin) * b.count / most;
    const x0 = X(b.from_us), x1 = X(b.to_us);
    g.fillRect(x0, canvas.height - margin - h, Math.max(1, x1 - x0 - 1), h);
  }
  g.fillStyle = '#555';
  g.fillText(`${bins[0].from_us.toPrecision(3)} µs`, margin, canvas.height - 8);
  const end = `${bins[bins.length - 1].to_us.toPrecision(3)} µs`;
  g.fillText(end, canvas.width - margin - g.measureText(end).width, canvas.height - 8);
  g.fillText(`${total} wake-ups, tallest bar ${most}`, margin, 14);
}

// Draws a projection (i, j: the axes) of the programmed path and the trace, same scale on both.
function drawPath(canvas, i, j) {
  const g = canvas.getContext('2d');
  g.clearRect(0, 0, canvas.width, canvas.height);
  const prog = program && lastStatus && program.job === lastStatus.job ? program.points : [];
  // The origin is always in view, with its axes (machine coordinates, the path's frame).
  let lo = [0, 0], hi = [0, 0];
  for (const set of [prog, trace]) {
    for (const p of set) {
      lo = [Math.min(lo[0], p[i]), Math.min(lo[1], p[j])];
      hi = [Math.max(hi[0], p[i]), Math.max(hi[1], p[j])];
    }
  }
  if (!prog.length && !trace.length) return;
  const margin = 16;
  const span = Math.max(hi[0] - lo[0], hi[1] - lo[1], 1e-3);
  const k = Math.min((canvas.width - 2 * margin) / Math.max(hi[0] - lo[0], span * 1e-3),
                     (canvas.height - 2 * margin) / Math.max(hi[1] - lo[1], span * 1e-3));
  const cx = (lo[0] + hi[0]) / 2, cy = (lo[1] + hi[1]) / 2;
  const X = (p) => canvas.width / 2 + (p[i] - cx) * k;
  const Y = (p) => canvas.height / 2 - (p[j] - cy) * k;
  const line = (pts, color, width) => {
    if (pts.length < 2) return;
    g.strokeStyle = color;
    g.lineWidth = width;
    g.beginPath();
    g.moveTo(X(pts[0]), Y(pts[0]));
    for (const p of pts) g.lineTo(X(p), Y(p));
    g.stroke();
  };
  // The axes through the origin, each with its name at the positive end.
  const names = ['X', 'Y', 'Z'];
  const o = [0, 0, 0];
  g.strokeStyle = '#cbd5e1';
  g.lineWidth = 1;
  g.beginPath();
  g.moveTo(0, Y(o)); g.lineTo(canvas.width, Y(o));
  g.moveTo(X(o), 0); g.lineTo(X(o), canvas.height);
  g.stroke();
  g.fillStyle = '#64748b';
  g.fillText(names[i], canvas.width - 12, Y(o) - 4);
  g.fillText(names[j], X(o) + 4, 24);
  g.beginPath();
  g.arc(X(o), Y(o), 3, 0, 2 * Math.PI);
  g.fill();
  line(prog, '#9ca3af', 3);
  line(trace, '#2563eb', 1.5);
  const at = trace[trace.length - 1];
  if (at) {
    g.fillStyle = '#dc2626';
    g.beginPath();
    g.arc(X(at), Y(at), 4, 0, 2 * Math.PI);
    g.fill();
  }
  g.fillStyle = '#555';
  g.fillText(`${span.toFixed(1)} mm`, 4, 12);
}

function drawFeed() {
  const canvas = $('feedplot');
  const g = canvas.getContext('2d');
  g.clearRect(0, 0, canvas.width, canvas.height);
  const now = performance.now() / 1000;
  let top = 1;
  for (const h of feedHistory) top = Math.max(top, h.feed, h.limit || 0);
  top *= 1.1;
  const X = (t) => 40 + (t - (now - kFeedWindowS)) / kFeedWindowS * (canvas.width - 50);
  const Y = (v) => canvas.height - 20 - v / top * (canvas.height - 30);
  g.strokeStyle = '#e5e7eb';
  g.fillStyle = '#555';
  for (let s = 0; s <= kFeedWindowS; s += 10) {
    g.beginPath(); g.moveTo(X(now - s), 10); g.lineTo(X(now - s), canvas.height - 20); g.stroke();
    g.fillText(`-${s} s`, X(now - s) - 12, canvas.height - 6);
  }
  g.fillText(`${top.toFixed(0)} mm/min`, 2, 12);
  const series = (key, color) => {
    g.strokeStyle = color;
    g.lineWidth = 1.5;
    g.beginPath();
    let open = false;
    for (const h of feedHistory) {
      const v = h[key];
      if (v === null || v === undefined) { open = false; continue; }
      if (open) g.lineTo(X(h.t), Y(v)); else g.moveTo(X(h.t), Y(v));
      open = true;
    }
    g.stroke();
  };
  series('limit', '#f59e0b');
  series('feed', '#2563eb');
}

let drawQueued = false;
function draw() {
  if (drawQueued) return;
  drawQueued = true;
  requestAnimationFrame(() => {
    drawQueued = false;
    drawPath($('xy'), 0, 1);
    drawPath($('xz'), 0, 2);
    drawFeed();
  });
}

// Controls.
$('start').onclick = () => request({ cmd: 'start' });
$('hold').onclick = () => request({ cmd: 'hold' });
$('resume').onclick = () => request({ cmd: 'resume' });
$('stop').onclick = () => request({ cmd: 'stop' });
$('cycle-start').onclick = () => {
  // A machine's cycle start: starts a job that is ready, resumes one that is held.
  const state = lastStatus && lastStatus.state;
  if (state === 'holding') request({ cmd: 'resume' });
  else request({ cmd: 'start' });
};
$('override-input').oninput = () => {
  overrideEditing = true;
  clearTimeout(overrideEditTimer);
  overrideEditTimer = setTimeout(() => { overrideEditing = false; }, kOverrideEditS * 1000);
  $('override-value').textContent = $('override-input').value;
};
$('override-set').onclick = async () => {
  await request({ cmd: 'override', percent: Number($('override-input').value) });
  clearTimeout(overrideEditTimer);
  overrideEditing = false;  // the next status shows what the service took
};
$('submit-file').onclick = async () => {
  const file = $('program-file').files[0];
  if (!file) {
    $('message').textContent = 'choose a program file first';
    return;
  }
  request({ cmd: 'upload', name: file.name, text: await file.text() });
};
$('chamfer').onsubmit = (event) => {
  event.preventDefault();
  const job = {};
  // The chamfer job's request keys (docs/cmd-chamfer.md; api/intake.cpp chamfer_job): numbers,
  // and edge and side as words.
  for (const input of event.target.querySelectorAll('input, select')) {
    if (input.value === '') continue;
    job[input.name] = input.tagName === 'SELECT' ? input.value : Number(input.value);
  }
  request({ cmd: 'submit', job });
};

enableControls(null);  // nothing is enabled before the first status
connect();
