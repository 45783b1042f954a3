// noisemon dash: the page's script. One EventSource on /events (it reconnects by itself; each new stream starts
// with the whole history), uPlot for the plots, and every number also as text in an element with an id.
'use strict';

const CYCLE_FLAGS = [[1, 'settling'], [2, 'gap'], [4, 'no-op'], [8, 'odd-length'], [16, 'no-mics'], [32, 'encoder'],
  [64, 'overload'], [128, 'mic-excluded'], [256, 'pressure-fault'], [512, 'lw-bound'], [1024, 'angle-gap']];
// BAND_* bits of cycle_report_t (msgs/cycle_report_t.lcm); 8, 16 and 32 keep a band out of the overall levels.
const BAND_FLAGS = [[1, 'nyquist-cut'], [2, 'slow'], [4, 'settling'], [8, 'below-firing'], [16, 'beyond-pressure-passband'],
  [32, 'beyond-mic-passband']];
const MIC_FLAGS = [[1, 'excluded'], [2, 'flat'], [4, 'overload'], [8, 'NaN'], [16, 'low']];
const THREAD_STATES = ['idle', 'running', 'stopped', 'FAILED'];
// Rows of the flag chart: the flags the operator watches for, and the rest together.
const FLAG_ROWS = ['dropped', 'settling', 'no-op', 'overload', 'other'];
const MAIN_FLAG_BITS = 1 | 4 | 64;

const $ = (id) => document.getElementById(id);
const isNum = (v) => typeof v === 'number' && Number.isFinite(v);
const fmt = (v, digits = 2) => (isNum(v) ? v.toFixed(digits) : 'n/a');
const bandLabel = (value) => {
  if (value == null) return '';
  const hz = Number(value);
  if (!isNum(hz)) return '';
  return hz >= 1000 ? `${+(hz / 1000).toFixed(2)}k` : `${+hz.toFixed(1)}`;
};
const flagNames = (flags, table) => table.filter(([bit]) => flags & bit).map(([, name]) => name);

const trend = { max: 600, t: [], lpaM: [], lpaP: [], lwaM: [], lwaP: [], speed: [], load: [], soi: [], rows: FLAG_ROWS.map(() => []) };
const seen = { received: 0, events: 0, restarts: 0, lastArrival: 0 };
const charts = {};
let bandHz = [];
let reference = null;  // the thesis's linear attenuation curve: { band_hz, att_db }, sent with the first event

function setText(id, text, cls) {
  const el = $(id);
  el.textContent = text;
  if (cls !== undefined) el.className = cls;
}

function chartWidth(el) { return Math.max(320, el.parentElement.clientWidth - 24); }

function line(label, stroke, extra = {}) {
  return Object.assign({ label, stroke, width: 1.5, points: { show: false } }, extra);
}

function dots(label, stroke) {
  return { label, stroke, fill: stroke, paths: () => null, points: { show: true, size: 7, fill: stroke } };
}

// Hollow grey rings over the points of flagged bands.
function flagged(label) {
  return { label, stroke: '#9e9e9e', paths: () => null, points: { show: true, size: 13, width: 2, stroke: '#9e9e9e', fill: 'rgba(0,0,0,0)' } };
}

function makeChart(id, height, scales, series, axes) {
  const el = $(id);
  const data = series.map(() => []);
  return new uPlot({ width: chartWidth(el), height, scales, series, axes }, data, el);
}

function makeTrendCharts() {
  const time = { x: { time: true } };
  charts.levels = makeChart('trend-levels', 220, time, [{},
    line('Lp(A) meas', '#1565c0'), line('Lp(A) pred', '#64b5f6', { dash: [6, 4] }),
    line('LW(A) meas', '#c62828'), line('LW(A) pred', '#ef9a9a', { dash: [6, 4] })], [{}, { label: 'dB(A)' }]);
  charts.context = makeChart('trend-context', 160, { x: { time: true }, rpm: {}, other: {} }, [{},
    line('speed rpm', '#455a64', { scale: 'rpm' }), line('load N m', '#6a1b9a', { scale: 'other' }),
    line('SOI °BTDC', '#00897b', { scale: 'other' })],
  [{}, { scale: 'rpm', label: 'rpm' }, { scale: 'other', side: 1, label: 'N m, °', grid: { show: false } }]);
  const colours = ['#000000', '#ef6c00', '#8e24aa', '#c62828', '#757575'];
  charts.flags = makeChart('trend-flags', 140, { x: { time: true }, y: { range: [0.5, FLAG_ROWS.length + 0.5] } },
    [{}, ...FLAG_ROWS.map((name, i) => dots(name, colours[i]))],
    [{}, { splits: () => FLAG_ROWS.map((_, i) => i + 1), values: (u, s) => s.map((v) => FLAG_ROWS[v - 1] || ''), size: 80 }]);
}

function makeBandCharts() {
  const logX = { x: { time: false, distr: 3, log: 10, range: (u, min, max) => [min / 1.15, max * 1.15] } };
  const bandAxis = { splits: () => bandHz, filter: (u, s) => s, values: (u, s) => s.map(bandLabel), rotate: -90, size: 50, label: 'band Hz' };
  const hz = { label: 'band', value: (u, v) => (v == null ? '' : bandLabel(v)) };
  charts.spectrum = makeChart('spectrum', 260, logX, [hz,
    line('measured dB(A)', '#1565c0', { points: { show: true } }),
    line('predicted dB(A)', '#c62828', { points: { show: true }, dash: [6, 4] }),
    flagged('flagged band')], [bandAxis, { label: 'dB(A)' }]);
  charts.attenuation = makeChart('attenuation', 260, logX, [hz,
    line('measured dB', '#1565c0', { points: { show: true } }),
    line('predicted dB', '#c62828', { points: { show: true }, dash: [6, 4] }),
    line('thesis linear model (Table 4.1)', '#2e7d32', { dash: [2, 3] }),
    flagged('flagged band')], [bandAxis, { label: 'dB' }]);
  charts.mics = makeChart('mic-chart', 200, { x: { time: false, range: (u, min, max) => [min - 0.6, max + 0.6] } },
    [{ label: 'mic' }, { label: 'Lp(A) dB(A)', stroke: '#1565c0', fill: '#90caf980', paths: uPlot.paths.bars({ size: [0.6, 60] }) }],
    [{ splits: (u) => u.data[0], values: (u, s) => s.map((v) => `mic${v}`) }, { label: 'dB(A)' }]);
}

// Appends trend points; `full` replaces the history (a new stream: first event after (re)connecting).
function addTrend(points, full) {
  if (full) for (const key of ['t', 'lpaM', 'lpaP', 'lwaM', 'lwaP', 'speed', 'load', 'soi']) trend[key] = [];
  if (full) trend.rows = FLAG_ROWS.map(() => []);
  for (const p of points) {
    if (p.restarted && trend.t.length > 0) {  // a break in the lines where the daemon restarted
      trend.t.push(p.t - 1e-3);
      for (const key of ['lpaM', 'lpaP', 'lwaM', 'lwaP', 'speed', 'load', 'soi']) trend[key].push(null);
      trend.rows.forEach((row) => row.push(null));
    }
    trend.t.push(p.t); trend.lpaM.push(p.lpa_m); trend.lpaP.push(p.lpa_p); trend.lwaM.push(p.lwa_m); trend.lwaP.push(p.lwa_p);
    trend.speed.push(p.speed); trend.load.push(p.load); trend.soi.push(p.soi);
    const on = [p.dropped > 0, p.flags & 1, p.flags & 4, p.flags & 64, p.flags & ~MAIN_FLAG_BITS];
    on.forEach((flag, i) => trend.rows[i].push(flag ? i + 1 : null));
    if (p.restarted && !full) seen.restarts += 1;
    if (!full) seen.received += 1;
  }
  const extra = trend.t.length - trend.max;
  if (extra > 0) {
    for (const key of ['t', 'lpaM', 'lpaP', 'lwaM', 'lwaP', 'speed', 'load', 'soi']) trend[key].splice(0, extra);
    trend.rows.forEach((row) => row.splice(0, extra));
  }
}

function drawTrend() {
  charts.levels.setData([trend.t, trend.lpaM, trend.lpaP, trend.lwaM, trend.lwaP]);
  charts.context.setData([trend.t, trend.speed, trend.load, trend.soi]);
  charts.flags.setData([trend.t, ...trend.rows]);
  const counts = FLAG_ROWS.map((name, i) => `${name} ${trend.rows[i].filter((v) => v !== null).length}`);
  setText('flag-counts', `(last ${trend.t.length} cycles: ${counts.join(', ')})`);
}

function showCycle(c) {
  if (!c || c.cycle === undefined) return;
  setText('cycle', String(c.cycle));
  $('cycle').dataset.utime = String(c.utime);  // which report this is, for tests and tools
  const names = flagNames(c.flags, CYCLE_FLAGS);
  setText('flags', names.length ? names.join(' ') : 'ok', names.length ? 'warn' : 'ok');
  setText('lpa-meas', fmt(c.lpa_measured_db)); setText('lpa-pred', fmt(c.lpa_predicted_db));
  setText('lwa-meas', fmt(c.lwa_measured_db)); setText('lwa-pred', fmt(c.lwa_predicted_db));
  setText('lpa-err', isNum(c.lpa_measured_db) && isNum(c.lpa_predicted_db) ? fmt(c.lpa_predicted_db - c.lpa_measured_db) : 'n/a');
  setText('lwa-err', isNum(c.lwa_measured_db) && isNum(c.lwa_predicted_db) ? fmt(c.lwa_predicted_db - c.lwa_measured_db) : 'n/a');
  setText('speed', fmt(c.speed_rpm, 1)); setText('load', fmt(c.load_nm, 1)); setText('soi', fmt(c.soi_deg_btdc, 1));
  setText('cycle-proc', fmt(c.processing_ms, 3)); setText('peak', fmt(c.peak_pressure_bar, 1)); setText('imep', fmt(c.imep_net_bar, 2));
  bandHz = c.band_hz;
  const mark = (values) => values.map((v, b) => (c.band_flags[b] ? v : null));
  charts.spectrum.setData([c.band_hz, c.spl_a_measured_db, c.spl_a_predicted_db, mark(c.spl_a_measured_db)]);
  charts.attenuation.setData([c.band_hz, c.att_measured_db, c.att_predicted_db, referenceAt(c.band_hz), mark(c.att_measured_db)]);
  showBandFlags(c.band_hz, c.band_flags);
  showMics(c.mic_lpa_db, c.mic_flags);
}

// The reference curve at the report's bands (matched by nominal frequency), null where it has none.
function referenceAt(bands) {
  if (!reference) return bands.map(() => null);
  return bands.map((hz) => {
    const i = reference.band_hz.findIndex((r) => Math.abs(r / hz - 1) < 0.01);
    return i < 0 ? null : reference.att_db[i];
  });
}

// Which bands are flagged and why, one reason at a time: "nyquist-cut 20k; below-firing 20, 25".
function showBandFlags(bands, flags) {
  const parts = BAND_FLAGS.map(([bit, name]) => {
    const hit = bands.filter((_, b) => flags[b] & bit).map(bandLabel);
    return hit.length ? `${name} ${hit.join(', ')}` : '';
  }).filter((part) => part);
  setText('band-flags', parts.length ? parts.join('; ') : 'none', parts.length ? 'warn' : 'ok');
}

function showMics(levels, flags) {
  charts.mics.setData([levels.map((_, i) => i + 1), levels]);
  const rows = ['<tr><th>mic</th><th>Lp(A) dB(A)</th><th>flags</th></tr>'];
  levels.forEach((level, i) => {
    const names = flagNames(flags[i], MIC_FLAGS);
    rows.push(`<tr><th>mic${i + 1}</th><td id="mic-${i + 1}">${fmt(level)}</td>`
      + `<td id="mic-${i + 1}-flags" class="${names.length ? 'bad' : 'ok'}">${names.length ? names.join(' ') : 'ok'}</td></tr>`);
  });
  $('mics').innerHTML = rows.join('');
}

function escapeHtml(s) { return String(s).replace(/[&<>"]/g, (ch) => `&#${ch.charCodeAt(0)};`); }

function showStatus(s) {
  if (!s || s.source === undefined) return;
  setText('source', s.source); setText('uptime', fmt(s.uptime_s, 0));
  setText('published', String(s.cycles_published)); setText('dropped', String(s.cycles_dropped), s.cycles_dropped > 0 ? 'warn' : '');
  setText('lat-mean', fmt(s.latency_ms_mean, 1)); setText('lat-max', fmt(s.latency_ms_max, 1));
  setText('proc-mean', fmt(s.processing_ms_mean, 3)); setText('proc-max', fmt(s.processing_ms_max, 3));
  $('threads').innerHTML = s.threads.map((t) => `<tr><th>${escapeHtml(t.name)}</th>`
    + `<td id="thread-${escapeHtml(t.name)}" class="${t.state === 1 ? 'ok' : 'bad'}">${THREAD_STATES[t.state] || '?'}</td>`
    + `<td>${escapeHtml(t.error)}</td></tr>`).join('');
  $('rings').innerHTML = '<tr><th></th><th>fill %</th><th>overruns</th></tr>' + s.rings.map((r) => `<tr><th>${escapeHtml(r.name)}</th>`
    + `<td id="ring-${escapeHtml(r.name)}-fill">${fmt(100 * r.fill, 1)}</td>`
    + `<td id="ring-${escapeHtml(r.name)}-overruns" class="${r.overruns > 0 ? 'warn' : ''}">${r.overruns}</td></tr>`).join('');
  $('counters').innerHTML = s.counters.map((c) => `<tr><th>${escapeHtml(c.name)}</th><td>${c.value}</td></tr>`).join('');
  setText('record-file', s.record_file || 'none');
}

// ---------------------------------------------------------------------------------------------- the recording

// A command to the daemon's recorder (POST /api/record); its answer, or why none came, under the buttons.
async function recordCommand(action, argument) {
  setText('record-answer', `${action}: waiting for the daemon…`, '');
  try {
    const response = await fetch('/api/record', { method: 'POST', body: JSON.stringify({ action, argument }) });
    const a = await response.json();
    const text = a.error || (a.ok ? 'done: ' : a.answered ? 'refused: ' : '') + (a.message || '') + (a.file ? ` (${a.file})` : '');
    setText('record-answer', text, a.ok ? 'ok' : 'bad');
  } catch (e) {
    setText('record-answer', `${action}: ${e}`, 'bad');
  }
}

$('record-start').onclick = () => recordCommand('start', $('record-test-point').value.trim());
$('record-stop').onclick = () => recordCommand('stop', '');
$('record-mark').onclick = () => recordCommand('mark', $('record-note').value.trim());

// ---------------------------------------------------------------------------------------------- the gap watch

const gap = { rows: [], t: [], bands: [], events: [] };

function addGapRows(points, full, bands) {
  if (full) { gap.rows = []; gap.t = []; }
  if (bands) gap.bands = bands;
  for (const p of points) if (p.gap) { gap.rows.push(p.gap); gap.t.push(p.t); }
  const extra = gap.rows.length - trend.max;
  if (extra > 0) { gap.rows.splice(0, extra); gap.t.splice(0, extra); }
}

// Heat map: one column per cycle, one row per band (low bands at the bottom), +-3 dB full scale; event onsets as lines.
function drawGapHeatmap() {
  const canvas = $('gap-heatmap');
  const cols = gap.rows.length, rows = cols ? gap.rows[0].length : 0;
  canvas.width = Math.max(1, cols); canvas.height = Math.max(1, rows);
  const ctx = canvas.getContext('2d');
  const img = ctx.createImageData(canvas.width, canvas.height);
  for (let x = 0; x < cols; ++x) {
    for (let b = 0; b < rows; ++b) {
      const v = gap.rows[x][b], i = 4 * ((rows - 1 - b) * cols + x);
      const s = v === null ? 0 : Math.max(-1, Math.min(1, v / 3));
      img.data[i] = v === null ? 230 : 255 - Math.round(255 * Math.max(0, -s));
      img.data[i + 1] = v === null ? 230 : 255 - Math.round(255 * Math.abs(s));
      img.data[i + 2] = v === null ? 230 : 255 - Math.round(255 * Math.max(0, s));
      img.data[i + 3] = 255;
    }
  }
  ctx.putImageData(img, 0, 0);
  ctx.fillStyle = '#000';
  for (const e of gap.events) {
    const onset = e.utime * 1e-6 - (e.detected_s - e.onset_s);
    const x = gap.t.findIndex((t) => t >= onset);
    if (x >= 0) ctx.fillRect(x, 0, 1, rows);
  }
}

function paramText(params) { return Object.entries(params).map(([k, v]) => `${k}=${Number(v).toPrecision(4)}`).join(' '); }

function showGapEvents(events, status) {
  gap.events = events || [];
  if (status && status.utime !== undefined) {
    setText('gap-status', status.learning ? '(learning the reference)'
      : `(${status.events} events · reference ${fmt(status.reference_s, 0)} s, complete ${fmt(status.since_reference_s, 0)} s ago · ${status.watched_features} features watched at ${status.operating_points} operating points)`);
  }
  $('gap-events').innerHTML = '<tr><th>detected</th><th>effect</th><th>parameters</th><th>kind</th><th>onset</th><th>confidence</th><th>gap before → after</th></tr>'
    + gap.events.slice().reverse().map((e, i) => `<tr data-i="${gap.events.length - 1 - i}"><td>${new Date(e.utime / 1000).toLocaleTimeString()}</td>`
      + `<td><b>${escapeHtml(e.effect)}</b></td><td>${escapeHtml(paramText(e.params))}</td><td>${escapeHtml(e.kind)}</td>`
      + `<td>${fmt(e.onset_s, 1)} s (cycle ${e.onset_cycle})</td><td>${fmt(e.confidence, 2)}</td>`
      + `<td>${fmt(e.gap_before_db, 2)} → ${fmt(e.gap_after_db, 2)} dB</td></tr>`).join('');
  for (const row of $('gap-events').querySelectorAll('tr[data-i]')) row.onclick = () => showEvidence(gap.events[Number(row.dataset.i)]);
}

// An event's evidence: what fired, the change per band and microphone, every candidate's weight.
function showEvidence(e) {
  const bands = e.band_hz.map((hz, b) => e.gap_change_db[b] === null ? null : `${hz} Hz ${e.gap_change_db[b] >= 0 ? '+' : ''}${e.gap_change_db[b].toFixed(2)}`)
    .filter((x) => x !== null).join(', ');
  const mics = e.mic_change_db.map((d, m) => `mic${m + 1} ${d === null ? '–' : d.toFixed(2)}`).join(', ');
  const candidates = e.candidates.map((c) => `${c.effect} ${c.weight.toFixed(3)}`).join(', ');
  $('gap-evidence').innerHTML = `<p><b>${escapeHtml(e.effect)}</b> ${escapeHtml(paramText(e.params))}: ${escapeHtml(e.explanation)}</p>`
    + `<p>fired: ${escapeHtml(e.features.join(', '))}</p><p>band gap change, dB: ${escapeHtml(bands)}</p>`
    + `<p>microphone level change, dB: ${escapeHtml(mics)}</p><p>candidates' weights: ${escapeHtml(candidates)}</p>`;
}

// ---------------------------------------------------------------------------------------------- the pre-test check

// noisemon check --publish's table: the rows and verdicts the terminal printed.
function showCheck(c) {
  if (!c || c.utime === undefined) return;
  setText('check-status', `(${new Date(c.utime / 1000).toLocaleString()} · ${c.source}, ${fmt(c.seconds, 0)} s · ${c.summary})`,
    c.problems > 0 ? 'bad' : 'ok');
  $('check-rows').innerHTML = '<tr><th>check</th><th>value</th><th>verdict</th></tr>' + c.rows.map((r) => `<tr><th>${escapeHtml(r.item)}</th>`
    + `<td>${escapeHtml(r.value)}</td><td class="${r.failed ? 'bad' : 'ok'}">${r.failed ? 'FAIL ' : ''}${escapeHtml(r.verdict)}</td></tr>`).join('');
}

function onEvent(message) {
  const e = JSON.parse(message.data);
  seen.events += 1;
  trend.max = e.history || trend.max;
  setText('cell-label', e.cell ? `cell ${e.cell}` : '');
  if (e.reference && e.reference.band_hz) reference = e.reference;
  if (e.trend.length > 0) seen.lastArrival = Date.now();
  addTrend(e.trend, e.full);
  drawTrend();
  addGapRows(e.trend, e.full, e.cycle && e.cycle.band_hz);
  showGapEvents(e.gap_events, e.gap_status);
  drawGapHeatmap();
  showCycle(e.cycle);
  showStatus(e.status);
  showCheck(e.check);
  setText('received', String(seen.received)); setText('events', String(seen.events)); setText('restarts', String(seen.restarts));
}

// EventSource retries by itself after a network error (the `retry` the server sends: 1 s); when the browser gives
// up (an HTTP error while the dash restarts), start a new one.
function connect() {
  const source = new EventSource('/events');
  source.onopen = () => setText('conn', 'live', 'ok');
  source.onmessage = onEvent;
  source.onerror = () => {
    setText('conn', 'reconnecting', 'bad');
    if (source.readyState === EventSource.CLOSED) setTimeout(connect, 2000);
  };
}

function tick() {
  if (!seen.lastArrival) return;
  const age = (Date.now() - seen.lastArrival) / 1000;
  setText('age', `${age.toFixed(1)} s`, age > 2 ? 'bad' : '');
}

function resize() {
  for (const chart of Object.values(charts)) chart.setSize({ width: chartWidth(chart.root.parentElement), height: chart.height });
}

makeTrendCharts();
makeBandCharts();
window.addEventListener('resize', resize);
setInterval(tick, 500);
connect();
