// The optobus console: devices, live values and charts from the server's event stream, the
// register map with edits the server checks, commands, frame traces. No library, no build step.
"use strict";

const CHART_MS = 5 * 60 * 1000; // what a chart shows
const CHART_STEP_MS = 100; // at most one chart point per 100 ms per value

const state = {
  devices: [], // from /api/devices
  cards: new Map(), // device name -> card parts
  series: new Map(), // "device/register" or "measurement:name" -> [[time, number], ...]
  dirty: new Set(), // charts to redraw
  measurements: new Map(), // measurement name -> card parts
  detail: null, // the device shown in detail
  map: null, // its register map
};

function el(tag, props, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(props || {})) {
    if (key === "class") node.className = value;
    else if (key === "data") for (const [k, v] of Object.entries(value)) node.dataset[k] = v;
    else if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
    else node[key] = value;
  }
  for (const child of children) node.append(child);
  return node;
}

function note(text) {
  document.getElementById("note").textContent = text;
}

function authorised(headers) {
  const token = sessionStorage.getItem("optobus-token");
  if (token) headers.authorization = "Bearer " + token;
  return headers;
}

async function api(path, body) {
  const options = body === undefined ? {} : {
    method: "POST",
    headers: { "content-type": "application/json" },
    body: JSON.stringify(body),
  };
  if (body !== undefined) authorised(options.headers);
  const response = await fetch(path, options);
  const json = await response.json().catch(() => ({ error: response.statusText }));
  if (!response.ok) {
    if (response.status === 401 && body !== undefined) {
      const given = window.prompt("This console needs its token for writes and reads of the line:");
      if (given) {
        sessionStorage.setItem("optobus-token", given.trim());
        return api(path, body);
      }
    }
    throw new Error(json.error || response.statusText);
  }
  return json;
}

// ---- devices and live values ----

function card(device) {
  const health = el("span", { class: "health" });
  const reason = el("div", { class: "reason" });
  const rows = el("tbody");
  const node = el("article", { class: "card", data: { device: device.device } },
    el("h2", {}, el("span", {}, device.device), health),
    el("div", { class: "facts" }, `${device.model} · line ${device.line} · slave ${device.slave} · ${device.title}`),
    reason,
    el("table", {}, rows),
    el("div", { class: "actions" },
      el("button", { type: "button", onclick: () => openDetail(device.device, "registers") }, "Registers"),
      el("button", { type: "button", onclick: () => openDetail(device.device, "commands") }, "Commands"),
      el("button", { type: "button", onclick: () => openDetail(device.device, "frames") }, "Frames"),
      el("button", { type: "button", onclick: () => exportValues(device.device) }, "Export CSV")));
  return { node, health, reason, rows, values: new Map(), groups: new Map() };
}

// A down device's last values stay on screen, marked as not current until sampled again.
function markCurrent(row, current) {
  row.value.classList.toggle("stale", !current);
  row.value.title = current ? "" : "not current: the device is down; its last value";
}

function showHealth(entry) {
  const parts = state.cards.get(entry.device);
  if (!parts) return;
  const offline = entry.health === "offline";
  parts.health.textContent = offline ? "offline" : "online";
  parts.health.classList.toggle("offline", offline);
  parts.reason.textContent = offline && entry.reason ? entry.reason : "";
  if (offline) for (const row of parts.values.values()) markCurrent(row, false);
}

function showSample(sample) {
  const parts = state.cards.get(sample.device);
  if (!parts) return;
  if (!Array.isArray(sample.fields)) {
    showValue(parts, sample, sample.register, sample.register, sample.text, sample.number);
    return;
  }
  // A packed or record register: a row per field of its spec, under a row naming it.
  if (!parts.groups.has(sample.register)) {
    const group = el("tr", { class: "group", data: { group: sample.register } },
      el("th", { colSpan: 3 }, sample.register));
    parts.groups.set(sample.register, group);
    parts.rows.append(group);
  }
  for (const field of sample.fields) {
    showValue(parts, sample, `${sample.register}.${field.name}`, field.name, field.text, field.number, "field");
  }
}

// One value's row: its label, its text and its chart (`name` is "register" or
// "register.field").
function showValue(parts, sample, name, label, text, number, kind) {
  const key = sample.device + "/" + name;
  let row = parts.values.get(name);
  if (!row) {
    const value = el("td", { class: "num", data: { value: key } });
    const chart = svgEl("svg", { class: "spark", "data-chart": key });
    row = { value, chart };
    parts.values.set(name, row);
    parts.rows.append(el("tr", { class: kind || "", data: { row: name } }, el("td", { class: "name" }, label), value, el("td", {}, chart)));
  }
  row.value.textContent = text;
  // Live samples are current; /api/values says so of the last ones.
  markCurrent(row, sample.current !== false);
  if (typeof number === "number") addPoint(key, sample.time, number);
}

// A point of a chart's series: at most one per CHART_STEP_MS (the latest stands), the last
// CHART_MS kept.
function addPoint(key, time, number) {
  let points = state.series.get(key);
  if (!points) state.series.set(key, (points = []));
  const last = points[points.length - 1];
  if (!last || time - last[0] >= CHART_STEP_MS) points.push([time, number]);
  else last[1] = number;
  while (points.length && points[0][0] < time - CHART_MS) points.shift();
  state.dirty.add(key);
}

const SVG = "http://www.w3.org/2000/svg";

function svgEl(tag, attributes, text) {
  const node = document.createElementNS(SVG, tag);
  for (const [key, value] of Object.entries(attributes || {})) node.setAttribute(key, value);
  if (text !== undefined) node.textContent = text;
  return node;
}

// As many decimals as tell apart values `span` apart.
function decimalsFor(span) {
  if (!(span > 0)) return 2;
  return Math.min(6, Math.max(0, 1 - Math.floor(Math.log10(span))));
}

// The local clock time of `time` (ms since 1970): 14:05:09.
function clock(time) {
  return new Date(time).toTimeString().slice(0, 8);
}

// Draws `points` ([time, number or null], oldest first) into the <svg> `box`, `width` ×
// `height`: the values' line (broken where a value is missing), a value axis labelled in
// `unit`, a time axis of clock times (`left`: room for the value labels), and each of `limits` (ll, lo, hi, hh) as a line.
function plot(box, points, { width, height, unit, limits, left }) {
  const right = 26, top = 8, bottom = 18;
  box.setAttribute("viewBox", `0 0 ${width} ${height}`);
  box.setAttribute("width", width);
  box.setAttribute("height", height);
  const given = Object.entries(limits || {}).filter(([, v]) => typeof v === "number");
  const numbers = points.map((p) => p[1]).filter((y) => typeof y === "number");
  const parts = [];
  if (!points.length || (!numbers.length && !given.length)) {
    box.replaceChildren();
    return;
  }
  let min = Math.min(...numbers, ...given.map((l) => l[1]));
  let max = Math.max(...numbers, ...given.map((l) => l[1]));
  const pad = (max - min) * 0.08 || Math.abs(max) * 0.01 || 1;
  min -= pad;
  max += pad;
  const end = points[points.length - 1][0];
  // Up to the last minutes; a younger series fills the chart.
  const shown = Math.min(CHART_MS, Math.max(end - points[0][0], 1000));
  const start = end - shown;
  const x = (t) => left + (width - left - right) * (t - start) / shown;
  const y = (v) => top + (height - top - bottom) * (max - v) / (max - min);
  // Axes: three values, three clock times.
  const decimals = decimalsFor(max - min);
  parts.push(svgEl("line", { class: "axis", x1: left, y1: top, x2: left, y2: height - bottom }));
  parts.push(svgEl("line", { class: "axis", x1: left, y1: height - bottom, x2: width - right, y2: height - bottom }));
  for (const v of [max - pad, (min + max) / 2, min + pad]) {
    parts.push(svgEl("line", { class: "grid", x1: left, y1: y(v), x2: width - right, y2: y(v) }));
    parts.push(svgEl("text", { class: "axis-label", "data-axis": "value", x: left - 4, y: y(v) + 3, "text-anchor": "end" },
      v.toFixed(decimals) + (unit ? " " + unit : "")));
  }
  // Three clock times where they fit, else the first and the last.
  const ticks = width >= 300 ? [[start, "start"], [start + shown / 2, "middle"], [end, "end"]] : [[start, "start"], [end, "end"]];
  ticks.forEach(([t, anchor]) => {
    parts.push(svgEl("text", { class: "axis-label", "data-axis": "time", x: x(t), y: height - 4, "text-anchor": anchor }, clock(t)));
  });
  for (const [name, v] of given) {
    parts.push(svgEl("line", { class: "limit limit-" + name, "data-limit": name, x1: left, y1: y(v), x2: width - right, y2: y(v) }));
    parts.push(svgEl("text", { class: "limit-label", x: width - right + 2, y: y(v) + 3 }, name.toUpperCase()));
  }
  let path = "";
  let pen = false;
  for (const [t, v] of points) {
    if (typeof v !== "number" || t < start) { pen = false; continue; }
    path += `${pen ? "L" : "M"}${x(t).toFixed(1)},${y(v).toFixed(1)}`;
    pen = true;
  }
  parts.push(svgEl("path", { class: "values", d: path }));
  box.replaceChildren(...parts);
}

function draw() {
  for (const key of state.dirty) {
    const points = state.series.get(key);
    if (!points || !points.length) continue;
    if (key.startsWith("measurement:")) {
      const parts = state.measurements.get(key.slice("measurement:".length));
      if (parts) plot(parts.chart, points, { width: 440, height: 200, unit: parts.unit, limits: parts.limits, left: 64 });
      continue;
    }
    const [device, register] = key.split("/");
    const row = state.cards.get(device)?.values.get(register);
    if (row) plot(row.chart, points, { width: 190, height: 64, unit: "", left: 40 });
  }
  state.dirty.clear();
  requestAnimationFrame(draw);
}

// ---- measurements ----

// A judgement as the page marks it: its text (readable without colour) and its class.
const JUDGEMENTS = {
  ll: "LL ▼▼", lo: "LO ▼", go: "GO ✓", hi: "HI ▲", hh: "HH ▲▲",
};

// A limit as the bus file wrote it: 10.2, not its nearest binary fraction.
function limitText(value) {
  return String(Number(value.toPrecision(12)));
}

function measurementCard(m) {
  const value = el("span", { class: "measurement-value", data: { measurementValue: m.measurement } });
  const badge = el("span", { class: "badge", data: { badge: m.measurement } });
  const reason = el("div", { class: "reason" });
  const facts = el("div", { class: "facts" });
  const chart = svgEl("svg", { class: "measurement-chart", "data-chart": "measurement:" + m.measurement });
  const stats = new Map();
  const statRow = (name, label) => {
    const cell = el("td", { class: "num", data: { stat: name } });
    stats.set(name, cell);
    return el("tr", {}, el("th", {}, label), cell);
  };
  const table = el("table", { class: "stats" }, el("tbody", {},
    statRow("count", "n"), statRow("mean", "mean"), statRow("sd", "sd"), statRow("min", "min"),
    statRow("max", "max"), statRow("range", "range"), statRow("cp", "Cp"), statRow("cpk", "Cpk")));
  const counts = el("div", { class: "facts", data: { counts: m.measurement } });
  const limits = m.limits
    ? Object.entries(m.limits).filter(([, v]) => v !== null).map(([k, v]) => `${k.toUpperCase()} ${limitText(v)} ${m.unit}`).join(" · ")
    : "no limits";
  const node = el("article", { class: "card measurement", data: { measurement: m.measurement } },
    el("h2", {}, el("span", {}, m.measurement), badge),
    el("div", { class: "reading" }, value),
    reason,
    el("div", { class: "facts" }, limits),
    facts,
    el("div", { class: "measurement-body" }, chart, table),
    counts);
  return { node, value, badge, reason, facts, chart, stats, counts, unit: m.unit, limits: m.limits };
}

function showCounts(parts, counts) {
  if (!counts) { parts.counts.textContent = ""; return; }
  const ng = counts.ll + counts.lo + counts.hi + counts.hh;
  parts.counts.textContent = `OK ${counts.go} · NG ${ng} (LL ${counts.ll}, LO ${counts.lo}, HI ${counts.hi}, HH ${counts.hh})`;
}

function showMeasurement(m) {
  const parts = state.measurements.get(m.measurement);
  if (!parts) return;
  const unit = m.unit ? " " + m.unit : "";
  parts.value.textContent = m.value === null ? "—" : m.value + unit;
  parts.reason.textContent = m.value === null ? m.reason || "" : "";
  parts.badge.textContent = m.judgement ? JUDGEMENTS[m.judgement] : "";
  parts.badge.className = "badge" + (m.judgement ? " judgement-" + m.judgement : "");
  parts.facts.textContent = `skew ${(m.skew_us / 1000).toFixed(2)} ms · ${clock(m.time)}`;
  // The value's own decimals for what is in its unit; three more for the spread.
  // An event without statistics leaves the last ones shown.
  if (m.stats) showStats(parts, m.stats, m.value === null ? 3 : (m.value.split(".")[1] || "").length, unit);
  addPoint("measurement:" + m.measurement, m.time, m.number);
}

// The statistics as the bus computed them: in the unit to the value's decimals (one more for
// the mean and the spread), Cp and Cpk to two.
function showStats(parts, stats, places, unit) {
  const text = {
    count: stats.count ?? "",
    mean: stats.mean === undefined ? "" : stats.mean.toFixed(places + 1) + unit,
    sd: stats.sd == null ? "—" : stats.sd.toFixed(places + 1) + unit,
    min: stats.min === undefined ? "" : stats.min.toFixed(places) + unit,
    max: stats.max === undefined ? "" : stats.max.toFixed(places) + unit,
    range: stats.range === undefined ? "" : stats.range.toFixed(places) + unit,
    cp: stats.cp == null ? "—" : stats.cp.toFixed(2),
    cpk: stats.cpk == null ? "—" : stats.cpk.toFixed(2),
  };
  for (const [name, cell] of parts.stats) cell.textContent = text[name];
}

async function loadMeasurements() {
  const { measurements } = await api("/api/measurements");
  const box = document.getElementById("measurements");
  box.hidden = measurements.length === 0;
  box.replaceChildren();
  state.measurements.clear();
  for (const m of measurements) {
    const parts = measurementCard(m);
    state.measurements.set(m.measurement, parts);
    box.append(parts.node);
    const key = "measurement:" + m.measurement;
    state.series.set(key, m.history.slice());
    state.dirty.add(key);
    if (m.latest) showMeasurement(m.latest);
    showCounts(parts, m.counts);
  }
}

// The OK/NG counts, which the stream does not carry: read again every few seconds.
async function refreshCounts() {
  if (!state.measurements.size) return;
  const { measurements } = await api("/api/measurements");
  for (const m of measurements) {
    const parts = state.measurements.get(m.measurement);
    if (parts) showCounts(parts, m.counts);
  }
}

function showLines(lines) {
  const text = lines.map((l) =>
    `${l.line}: ${l.open ? "open" : "CLOSED"}, ${l.transactions} transactions, ` +
    `${Math.round(l.utilisation * 100)} % busy`).join(" · ");
  document.getElementById("summary").textContent =
    `${state.devices.length} device${state.devices.length === 1 ? "" : "s"}` + (text ? " · " + text : "");
}

async function load() {
  const [devices, values] = await Promise.all([api("/api/devices"), api("/api/values")]);
  state.devices = devices.devices;
  const box = document.getElementById("devices");
  box.replaceChildren();
  state.cards.clear();
  for (const device of state.devices) {
    const parts = card(device);
    state.cards.set(device.device, parts);
    box.append(parts.node);
    showHealth(device);
  }
  for (const samples of Object.values(values)) samples.forEach(showSample);
  showLines(devices.lines);
  await loadMeasurements();
}

function connect() {
  const link = document.getElementById("link");
  const source = new EventSource("/api/stream");
  source.onopen = () => {
    link.textContent = "stream: live";
    link.classList.remove("down");
    // After a restart of the server the devices may be others: read them again.
    load().catch((e) => note(e.message));
  };
  source.onerror = () => {
    link.textContent = "stream: reconnecting…";
    link.classList.add("down");
  };
  source.onmessage = (message) => {
    const batch = JSON.parse(message.data);
    batch.samples.forEach(showSample);
    batch.health.forEach(showHealth);
    if (batch.lines.length) showLines(batch.lines);
    batch.measurements.forEach(showMeasurement);
  };
  source.addEventListener("dropped", (message) => note(`the page fell behind: ${message.data} batches skipped`));
}

function download(name, rows) {
  save(name, rows.map((r) => r.map((c) => /[",\n]/.test(String(c)) ? `"${String(c).replace(/"/g, '""')}"` : c).join(",")).join("\n") + "\n");
}

function save(name, text) {
  const link = el("a", { href: URL.createObjectURL(new Blob([text], { type: "text/csv" })), download: name });
  document.body.append(link);
  link.click();
  link.remove();
}

function exportValues(device) {
  const rows = [["time", "register", "value"]];
  for (const [key, points] of state.series) {
    const [owner, register] = key.split("/");
    if (owner !== device) continue;
    for (const [t, y] of points) rows.push([new Date(t).toISOString(), register, y]);
  }
  download(`${device}.csv`, rows);
}

// ---- detail: register map, commands, frames ----

function tab(name) {
  for (const t of ["registers", "commands", "frames", "buffer"]) {
    document.getElementById("tab-" + t).hidden = t !== name;
  }
  if (name === "frames") loadFrames().catch((e) => note(e.message));
}

async function openDetail(device, which) {
  state.detail = device;
  state.map = await api(`/api/devices/${encodeURIComponent(device)}`);
  document.getElementById("detail").hidden = false;
  document.getElementById("detail-title").textContent = `${device} · ${state.map.title}`;
  document.getElementById("buffer-tab").hidden = !state.map.buffer;
  showMap();
  showCommands();
  tab(which);
  document.getElementById("detail").scrollIntoView();
}

function showMap() {
  const filter = document.getElementById("register-filter").value.trim().toLowerCase();
  const rows = document.getElementById("map-rows");
  rows.replaceChildren();
  for (const r of state.map.registers) {
    if (filter && !r.name.includes(filter) && !r.doc.toLowerCase().includes(filter)) continue;
    const current = el("td", { class: "num" });
    const edit = el("td", {});
    if (r.writable) {
      const input = el("input", { type: "text", size: 10, placeholder: r.unit ? "value " + r.unit : "value" });
      const message = el("div", { class: "refusal" });
      const set = async () => {
        message.className = "refusal";
        message.textContent = "";
        try {
          const done = await api(`/api/devices/${encodeURIComponent(state.detail)}/set`, { register: r.name, value: input.value });
          message.className = "accepted";
          message.textContent = "set: " + done.text;
          current.textContent = done.text;
        } catch (e) {
          message.textContent = e.message;
        }
      };
      input.addEventListener("keydown", (e) => { if (e.key === "Enter") set(); });
      edit.append(input, el("button", { type: "button", data: { action: "set" }, onclick: set }, "Set"), message);
    }
    const readable = !r.access.startsWith("w");
    const read = el("button", { type: "button", hidden: !readable, data: { action: "read" }, onclick: async () => {
      try {
        const got = await api(`/api/devices/${encodeURIComponent(state.detail)}/read`, { register: r.name });
        current.textContent = got.text;
      } catch (e) { current.textContent = e.message; }
    } }, "Read");
    rows.append(el("tr", { data: { register: r.name } },
      el("td", {}, el("div", {}, r.name), el("div", { class: "doc" }, r.doc + (r.manual_name ? ` (manual: ${r.manual_name})` : ""))),
      el("td", {}, `${r.address_hex} (${r.address})`),
      el("td", {}, r.table),
      el("td", {}, `${r.type} · ${r.access}`),
      el("td", {}, r.unit || ""),
      el("td", {}, r.range),
      el("td", {}, r.section),
      el("td", {}, current, read),
      edit));
  }
}

function showCommands() {
  const list = document.getElementById("command-list");
  const result = document.getElementById("command-result");
  list.replaceChildren();
  result.textContent = "";
  for (const c of state.map.commands) {
    const run = async () => {
      if (c.drastic && !window.confirm(`${c.name} on ${state.detail}: ${c.doc}\nThis changes the device. Go on?`)) {
        result.textContent = `${c.name}: not done`;
        return;
      }
      result.textContent = `${c.name}: running…`;
      try {
        await api(`/api/devices/${encodeURIComponent(state.detail)}/do`, { command: c.name });
        result.textContent = `${c.name}: done`;
      } catch (e) {
        result.textContent = `${c.name}: ${e.message}`;
      }
    };
    list.append(el("li", {},
      el("button", {
        type: "button", data: { command: c.name }, onclick: run, disabled: !c.allowed,
        title: c.allowed ? "" : "the bus file's `writable` does not list it",
      }, c.name + (c.drastic ? " …" : "")),
      " " + c.doc));
  }
}

let frames = [];
async function loadFrames() {
  frames = await api(`/api/devices/${encodeURIComponent(state.detail)}/frames`);
  const rows = document.getElementById("frame-rows");
  rows.replaceChildren(...frames.slice().reverse().map((f) => el("tr", { class: f.direction },
    el("td", {}, f.time.slice(11, 26)),
    el("td", {}, f.direction === "sent" ? "→" : "←"),
    el("td", {}, f.after_us === null ? "" : (f.after_us / 1000).toFixed(1) + " ms"),
    el("td", {}, f.hex))));
}

let bufferCsv = "";
async function readBuffer() {
  const result = document.getElementById("buffer-result");
  result.textContent = "reading out…";
  const response = await fetch(`/api/devices/${encodeURIComponent(state.detail)}/buffer`,
    { method: "POST", headers: authorised({}) });
  if (!response.ok) {
    const json = await response.json().catch(() => ({ error: response.statusText }));
    result.textContent = json.error;
    return;
  }
  bufferCsv = await response.text();
  const [header, ...rows] = bufferCsv.trim().split("\n");
  const columns = header.split(",");
  const points = rows.map((r) => r.split(",")).filter((c) => c[c.length - 1] !== "")
    .map((c) => [Number(c[columns.length === 3 ? 1 : 0]), Number(c[c.length - 1])]);
  result.textContent = `${rows.length} values (${columns[columns.length - 1]} over ${columns.length === 3 ? "time [s]" : "index"})`;
  document.getElementById("buffer-csv").disabled = false;
  const canvas = document.getElementById("buffer-plot");
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, canvas.width, canvas.height);
  if (!points.length) return;
  const xs = points.map((p) => p[0]), ys = points.map((p) => p[1]);
  const [x0, x1] = [Math.min(...xs), Math.max(...xs)], [y0, y1] = [Math.min(...ys), Math.max(...ys)];
  g.strokeStyle = "#0969da";
  g.beginPath();
  points.forEach(([x, y], i) => {
    const px = 10 + (canvas.width - 20) * (x - x0) / ((x1 - x0) || 1);
    const py = canvas.height - 10 - (canvas.height - 20) * (y - y0) / ((y1 - y0) || 1);
    if (i === 0) g.moveTo(px, py); else g.lineTo(px, py);
  });
  g.stroke();
  g.fillStyle = "#57606a";
  g.fillText(`${y1}`, 12, 12);
  g.fillText(`${y0}`, 12, canvas.height - 12);
}

document.addEventListener("DOMContentLoaded", () => {
  for (const button of document.querySelectorAll("[data-tab]")) {
    button.addEventListener("click", () => tab(button.dataset.tab));
  }
  document.getElementById("close-detail").addEventListener("click", () => { document.getElementById("detail").hidden = true; });
  document.getElementById("register-filter").addEventListener("input", showMap);
  document.getElementById("frames-refresh").addEventListener("click", () => loadFrames().catch((e) => note(e.message)));
  document.getElementById("frames-csv").addEventListener("click", () =>
    download(`${state.detail}-frames.csv`, [["time", "direction", "after_us", "bytes"], ...frames.map((f) => [f.time, f.direction, f.after_us ?? "", f.hex])]));
  document.getElementById("buffer-read").addEventListener("click", () => readBuffer().catch((e) => note(e.message)));
  document.getElementById("buffer-csv").addEventListener("click", () => save(`${state.detail}-buffer.csv`, bufferCsv));
  connect();
  setInterval(() => refreshCounts().catch((e) => note(e.message)), 2000);
  requestAnimationFrame(draw);
});
