// dnet-master console: three views over the JSON API (see master-harness/src/ui/mod.rs).
// Plain JavaScript, no library, nothing loaded from outside: the page works offline.
"use strict";

const $ = (id) => document.getElementById(id);
const el = (tag, attrs, ...kids) => {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") e.className = v; else if (k === "text") e.textContent = v; else e.setAttribute(k, v);
  }
  for (const k of kids) e.append(k);
  return e;
};

// ---- networks (dnet-master ui --plant: scanner/src/ui/networks.rs) ----------------------------
// The network shown (null: the console runs one). Its requests go to /api/net/NAME/...; logins,
// the audit log and the list of networks are the plant's.
let NET = null;
const PLANT_WIDE = /^\/api\/(login|logout|session|token|audit|networks)(\/|\?|$)/;
const netPath = (path) =>
  NET && path.startsWith("/api/") && !PLANT_WIDE.test(path) ? `/api/net/${encodeURIComponent(NET)}/${path.slice(5)}` : path;

// Asked until answered (before a login it is refused).
let networksKnown = false;
function showNetworks(r) {
  if (!r || !r.ok) return;
  networksKnown = true;
  const nets = r.networks || [];
  if (!nets.length) return;
  const bar = $("networks");
  bar.replaceChildren(...nets.map((n) => {
    const b = el("button", { type: "button", class: "net-tab", "data-network": n.name, title: n.bus, text: n.name });
    b.addEventListener("click", () => selectNetwork(n.name));
    return b;
  }));
  bar.hidden = false;
  selectNetwork(NET || nets[0].name);
}

function selectNetwork(name) {
  if (NET !== name) {
    NET = name;
    // Another network's frames, events and nodes: start afresh.
    traceFilter = ""; eventsSeen = 0; eventRows.length = 0; currentMac = null;
    if (location.hash.startsWith("#/node")) location.hash = "#/network";
  }
  for (const b of $("networks").children) b.classList.toggle("active", b.dataset.network === NET);
  refreshState();
}

async function api(path, opts) {
  const r = await fetch(netPath(path), opts);
  let body;
  try { body = await r.json(); } catch (_) { body = { ok: false, error: `HTTP ${r.status}` }; }
  if (!r.ok && body.ok !== false) body = { ok: false, error: `HTTP ${r.status}` };
  // No session (never logged in, logged out, or it expired): the login form.
  if (r.status === 401 && body.login) showLogin();
  return body;
}
// Every change carries the token (the server refuses it otherwise, as it refuses other origins
// and other content types): the page's without logins, the session's with them (scanner/src/ui/auth.rs).
let TOKEN = (document.querySelector('meta[name="csrf-token"]') || {}).content || "";
const post = (path, body) => api(path, {
  method: "POST",
  headers: { "Content-Type": "application/json", "X-CSRF-Token": TOKEN },
  body: JSON.stringify(body ?? {}),
});

let state = null;
let currentMac = null;

// ---- routing ---------------------------------------------------------------------------------
function route() {
  const h = location.hash || "#/network";
  const m = h.match(/^#\/node\/(\d+)/);
  const view = loginShown ? "login" : m ? "device" : h.startsWith("#/trace") ? "trace"
    : h.startsWith("#/audit") ? "audit" : h.startsWith("#/node") ? "device" : "network";
  if (m) currentMac = Number(m[1]);
  $("view-login").hidden = view !== "login";
  for (const v of ["network", "device", "trace", "audit"]) {
    $("view-" + v).hidden = v !== view;
    $("nav-" + v).classList.toggle("active", v === view);
  }
  if (view === "audit") refreshAudit();
  if (currentMac !== null) $("nav-device").href = "#/node/" + currentMac;
  if (view === "device") { lastNodeMac = null; refreshNode(); refreshPlot(); }
  if (view === "trace") refreshTrace();
}
window.addEventListener("hashchange", route);

// ---- network view ----------------------------------------------------------------------------
function buildGrid() {
  const grid = $("mac-grid");
  for (let mac = 0; mac < 64; mac++) {
    const c = el("div", { class: "cell st-empty", id: "cell-" + mac, "data-mac": mac },
      el("span", { class: "code" }), el("div", { class: "mac", text: "MAC " + mac }),
      el("div", { class: "name" }), el("div", { class: "sizes" }), el("div", { class: "status" }));
    c.addEventListener("click", () => { if (c.classList.contains("in-list")) location.hash = "#/node/" + mac; });
    grid.append(c);
  }
}

// The node's I/O connection as the scan list names it, "-ack" under acknowledge suppression.
function connectionName(n) { return (n.connection || "poll") + (n.ack_suppression ? " -ack" : ""); }

function fmtPct(x) { return (100 * (x || 0)).toFixed(1) + " %"; }

function renderState(s) {
  state = s;
  const line = (NET ? `network ${NET} · ` : "") + `scanner MAC ${s.mac} · ${s.status} · cycle ${Number(s.cycle_ms).toFixed(1)} ms · bus load ${fmtPct(s.bus_load)}`
    + ` · MQTT: ${s.mqtt || "off"}` + (s.recording ? " · ● recording" : "");
  $("scanner-line").textContent = line;
  const sum = $("net-summary");
  sum.replaceChildren(
    el("span", {}, "scanner ", el("b", { id: "scanner-status", text: s.status })),
    el("span", {}, "cycles ", el("b", { text: String(s.cycles) })),
    el("span", {}, "cycle ", el("b", { text: Number(s.cycle_ms).toFixed(1) + " ms" })),
    el("span", {}, "bus load ", el("b", { id: "bus-load", text: fmtPct(s.bus_load) })),
    el("span", {}, "EPR ", el("b", { text: s.expected_packet_rate_ms + " ms" })),
    el("span", {}, "inter-scan delay ", el("b", { text: s.interscan_delay_ms + " ms" })),
    el("span", {}, "MQTT ", el("b", { id: "mqtt-status", text: s.mqtt || "off" })));
  const byMac = new Map(s.nodes.map((n) => [n.mac, n]));
  for (let mac = 0; mac < 64; mac++) {
    const c = $("cell-" + mac);
    const n = byMac.get(mac);
    const [code, name, sizes, status] = c.querySelectorAll(".code, .name, .sizes, .status");
    if (!n) {
      c.className = "cell st-empty" + (mac === s.mac ? " scanner" : "");
      code.textContent = ""; name.textContent = mac === s.mac ? "(this scanner)" : "";
      sizes.textContent = ""; status.textContent = "";
      continue;
    }
    c.className = "cell in-list st-" + n.status;
    code.textContent = String(n.code);
    // The scan list's name first, then the product name read.
    name.textContent = [n.name, n.identity.product_name].filter(Boolean).join(" · ");
    sizes.textContent = `${connectionName(n)} · in ${n.input_size ?? "?"} · out ${n.output_size ?? "?"}`;
    status.textContent = n.status.replace(/_/g, " ");
    c.title = n.detail || n.status;
  }
}

async function refreshState() {
  if (!networksKnown) api("/api/networks").then(showNetworks);
  try { renderState(await api("/api/state")); } catch (e) { $("scanner-line").textContent = "console unreachable"; }
}

// ---- device view -----------------------------------------------------------------------------
let lastNodeMac = null;
let lastCommand = null;

function kvRows(table, rows) {
  table.replaceChildren(...rows.map(([k, v, key]) =>
    el("tr", key ? { "data-field": key } : {}, el("td", { text: k }), el("td", { class: "val", text: v ?? "–" }))));
}

async function refreshNode() {
  if (currentMac === null) { $("dev-title").textContent = "Device: choose a node in the network view"; return; }
  const r = await api("/api/node/" + currentMac);
  if (!r.ok) { $("dev-title").textContent = `MAC ${currentMac}: ${r.error}`; return; }
  const n = r.node, id = n.identity;
  $("dev-title").textContent = `MAC ${n.mac}${n.name ? " · " + n.name : ""} · ${id.product_name || "unknown product"} · ${n.status.replace(/_/g, " ")} (${n.code})`;
  const hex4 = (v) => v == null ? null : "0x" + v.toString(16).toUpperCase().padStart(4, "0");
  kvRows($("dev-identity"), [
    ["name (scan list)", n.name], ["product name", id.product_name], ["vendor ID", hex4(id.vendor_id)], ["device type", hex4(id.device_type)],
    ["product code", id.product_code == null ? null : String(id.product_code)], ["revision", id.revision],
    ["serial number", id.serial_number == null ? null : "0x" + id.serial_number.toString(16).toUpperCase().padStart(8, "0")],
    ["I/O connection", (n.connection || "poll") + (n.ack_suppression ? ", acknowledge suppression" : "")],
    ["I/O sizes", `in ${n.input_size ?? "?"} · out ${n.output_size ?? "?"}`], ["exchanges", String(n.exchanges)],
    ["status", `${n.status} (${n.code})${n.detail ? ": " + n.detail : ""}`],
  ]);
  $("dev-profile").textContent = r.profile + (r.with_status ? " + status byte" : "");
  const labels = { phase_a: "phase A", phase_b: "phase B", phase_c: "phase C", neutral: "neutral", switch: "switch state" };
  const rows = r.fields.map((f) => [labels[f.name] || f.name.replace(/^param_/, "parameter "), f.text, f.name]);
  if (!rows.length) rows.push(["raw input", r.input_hex || "(no data)", "raw"]);
  if (r.note) rows.push(["note", r.note, "note"]);
  kvRows($("dev-fields"), rows);
  const link = $("dev-link");
  if (r.link) {
    link.textContent = `status byte 0x${r.link.status.toString(16).padStart(2, "0").toUpperCase()}: ${r.link.text}`;
    link.className = "link" + (r.link.stale ? " stale" : "");
  } else {
    link.textContent = r.profile === "raw" ? "no profile known: raw bytes" : "input assembly 100: no status byte";
    link.className = "link";
  }
  $("dev-input").textContent = r.input_hex || "–";
  $("dev-output").textContent = r.output_hex || "–";
  $("breaker-card").hidden = r.profile !== "breaker";
  if (lastCommand && r.profile === "breaker") showOutcome(r);
  if (lastNodeMac !== n.mac) {
    lastNodeMac = n.mac;
    $("params").textContent = "";
    $("explicit-result").textContent = "";
    $("cmd-outcome").textContent = "";
    lastCommand = null;
    serialReset();
  }
  const now = Date.now();
  $("export-csv").href = netPath(`/api/export.csv?mac=${n.mac}&from=${now - 3600e3}&to=${now + 1000}`);
}

// The outcome of the last breaker command: status bits 4-6 with assembly 101, else the switch.
function showOutcome(r) {
  const out = $("cmd-outcome");
  const sw = (r.fields.find((f) => f.name === "switch") || {}).text;
  let text = `${lastCommand.label} sent (sequence ${lastCommand.sequence})`;
  if (r.link) text += ` · outcome: ${r.link.command}`;
  if (lastCommand.label === "close" || lastCommand.label === "open") text += ` · switch ${sw || "?"}`;
  const done = lastCommand.label === "close" ? sw === "closed" : lastCommand.label === "open" ? sw === "open" : false;
  const failed = r.link && ["rejected", "failed", "unsupported"].includes(r.link.command);
  out.textContent = text;
  out.className = "outcome " + (failed ? "err" : done || (r.link && r.link.command === "ok") ? "ok" : "");
}

async function breakerCommand(action, body) {
  const out = $("cmd-outcome");
  if (action !== "param") {
    const node = ((state && state.nodes) || []).find((n) => n.mac === currentMac) || {};
    const name = node.name || (node.identity && node.identity.product_name) || "";
    const asked = `${action === "open" ? "Open" : "Close"} the breaker at MAC ${currentMac}${name ? ` (${name})` : ""}?`;
    if (!(await confirmStep(asked))) { out.className = "outcome"; out.textContent = `${action}: cancelled`; return; }
  }
  out.className = "outcome"; out.textContent = action + "…";
  const r = await post(`/api/node/${currentMac}/breaker/${action}`, body || {});
  if (!r.ok) { out.className = "outcome err"; out.textContent = `${action}: ${r.error}`; lastCommand = null; return; }
  lastCommand = { label: action === "param" ? `set parameter ${body.id} = ${body.value}` : action, sequence: r.sequence };
  refreshNode();
}

// ---- live plot (canvas) ----------------------------------------------------------------------
const COLORS = ["#1f5fbf", "#c62828", "#2e9d48", "#e08a00", "#7b3fbf", "#00838f", "#6d4c41", "#ad1457"];
const PLOT_WINDOW = 60e3;

// The y axis up to `top`: a round step (1, 2 or 5 times a power of ten) giving 2 to 4 intervals,
// labels with the decimals the step needs, so no two read the same (rounding to whole numbers
// labelled 0.5 and 1.5 alike, "2, 2, 1, 1, 0").
function yTicks(top) {
  const t = top > 0 ? top : 1;
  const raw = t / 4;
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw * (1 - 1e-9));
  const n = Math.max(1, Math.ceil(t / step - 1e-9));
  const decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
  const ticks = Array.from({ length: n + 1 }, (_, i) => i * step);
  return { max: n * step, ticks, labels: ticks.map((v) => v.toFixed(decimals)) };
}

function drawPlot(samples, from, to) {
  const cv = $("plot");
  const dpr = window.devicePixelRatio || 1;
  const w = cv.clientWidth || 1000, h = cv.clientHeight || 260;
  cv.width = w * dpr; cv.height = h * dpr;
  const g = cv.getContext("2d");
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, w, h);
  const series = new Map();
  for (const s of samples) {
    for (const [name, v] of s.values) {
      if (name === "switch" || name === "status" || name === "freshness") continue;
      if (!series.has(name)) series.set(name, []);
      series.get(name).push([s.unix_ms, v]);
    }
  }
  let top = 0;
  for (const pts of series.values()) for (const [, v] of pts) top = Math.max(top, v);
  const axis = yTicks(top * 1.05);
  const max = axis.max;
  cv.dataset.yLabels = axis.labels.join(",");
  const L = 46, R = 10, T = 10, B = 24;
  const x = (t) => L + (w - L - R) * (t - from) / (to - from);
  const y = (v) => T + (h - T - B) * (1 - v / max);
  g.strokeStyle = "#e3e6ea"; g.fillStyle = "#69737f"; g.font = "11px system-ui, sans-serif"; g.lineWidth = 1;
  axis.ticks.forEach((v, i) => {
    const yy = y(v);
    g.beginPath(); g.moveTo(L, yy); g.lineTo(w - R, yy); g.stroke();
    g.fillText(axis.labels[i], 4, yy + 4);
  });
  for (let s = 0; s <= 60; s += 10) {
    const xx = x(to - s * 1000);
    g.fillText(s ? `-${s} s` : "now", xx - 12, h - 6);
  }
  const legend = [];
  let i = 0;
  for (const [name, pts] of series) {
    const c = COLORS[i++ % COLORS.length];
    g.strokeStyle = c; g.lineWidth = 2; g.beginPath();
    pts.forEach(([t, v], k) => (k ? g.lineTo(x(t), y(v)) : g.moveTo(x(t), y(v))));
    g.stroke();
    const last = pts[pts.length - 1];
    legend.push(el("span", {}, el("i", { style: "background:" + c }), `${name} ${last ? last[1] : ""}`));
  }
  if (!series.size) { g.fillStyle = "#69737f"; g.fillText("no samples in the last 60 s", L + 10, T + 20); }
  $("plot-legend").replaceChildren(...legend);
}

async function refreshPlot() {
  if (currentMac === null || $("view-device").hidden) return;
  const to = Date.now(), from = to - PLOT_WINDOW;
  const r = await api(`/api/history?mac=${currentMac}&from=${from}&to=${to}&limit=2000`);
  if (!r.ok) { $("plot-legend").textContent = r.error; drawPlot([], from, to); return; }
  drawPlot(r.samples, from, to);
}

// ---- explicit and parameters -----------------------------------------------------------------
async function explicit(op) {
  const out = $("explicit-result");
  const body = { class: $("ex-class").value, instance: $("ex-instance").value, attribute: $("ex-attribute").value };
  if (op === "set") body.value = $("ex-value").value;
  out.className = "outcome"; out.textContent = op + "…";
  const r = await post(`/api/node/${currentMac}/${op}`, body);
  out.className = "outcome " + (r.ok ? "ok" : "err");
  out.textContent = r.ok ? (op === "get" ? `${r.data || "(empty)"} · ${r.text}` : "set: ok") : `${op}: ${r.error}`;
}

async function readParams() {
  const box = $("params");
  box.textContent = "reading…";
  const r = await api(`/api/node/${currentMac}/params`);
  if (!r.ok) { box.textContent = r.error; return; }
  if (!r.params.length) { box.textContent = r.note || "none"; return; }
  const head = el("tr", {}, ...["#", "name", "value", "units", "min", "max", "default", "type", ""].map((t) => el("th", { text: t })));
  const rows = r.params.map((p) => el("tr", {},
    ...[p.number, p.name, p.value ?? p.raw, p.units, p.min, p.max, p.default,
      "0x" + p.data_type.toString(16).toUpperCase(), p.read_only ? "read-only" : ""].map((t) => el("td", { text: t == null ? "–" : String(t) }))));
  box.replaceChildren(el("table", { class: "params" }, el("thead", {}, head), el("tbody", {}, ...rows)));
}

// ---- trace view ------------------------------------------------------------------------------
let traceAfter = 0;
let traceFilter = "";
const TRACE_ROWS = 1000;

async function refreshTrace() {
  if ($("view-trace").hidden || $("tr-pause").checked) return;
  const mac = $("tr-mac").value, kind = $("tr-kind").value;
  const filter = `mac=${mac}&kind=${kind}`;
  const body = $("trace-table").tBodies[0];
  if (filter !== traceFilter) { traceFilter = filter; traceAfter = 0; body.replaceChildren(); }
  const r = await api(`/api/frames?after=${traceAfter}&${filter}&limit=${TRACE_ROWS}`);
  // An answer to a request made before the filter changed (or overtaken by a later one) is
  // dropped: its rows belong to the old filter.
  if (!r.ok || filter !== traceFilter || r.next < traceAfter) return;
  traceAfter = r.next;
  const rows = r.frames.map((f) => el("tr", { class: f.own ? "own" : "" },
    el("td", { text: String(f.seq) }), el("td", { text: (f.time_us / 1e6).toFixed(6) }),
    el("td", { text: f.own ? "→" : "←" }), el("td", {}, el("code", { text: f.frame })),
    el("td", { text: f.mac == null ? "" : String(f.mac) }), el("td", { text: f.kind }),
    el("td", { class: "meaning", text: f.meaning + (f.message ? " ⇒ " + f.message : "") })));
  body.prepend(...rows.reverse());
  while (body.rows.length > TRACE_ROWS) body.deleteRow(body.rows.length - 1);
}

// Start/Stop clicks so far: a recording status asked before the last one is stale. While a
// Start or Stop is on its way the status is not asked at all: its outcome is what the page shows.
let recordSeq = 0;
let recordBusy = false;

async function recordCommand(command, verb) {
  recordSeq++;
  recordBusy = true;
  try {
    showRecord(await post(`/api/record/${command}`, {}), verb);
  } finally {
    recordBusy = false;
  }
}

function showRecord(r, verb) {
  const out = $("rec-files");
  out.className = "outcome " + (r.ok ? "ok" : "err");
  if (!r.ok) { out.textContent = r.error; return; }
  $("rec-start").disabled = r.recording; $("rec-stop").disabled = !r.recording;
  out.textContent = r.recording === false && !verb ? "not recording" :
    `${verb || "recording"}: ${r.log} and ${r.pcap} · ${r.frames} frames` + (r.missed ? ` (${r.missed} missed)` : "");
}

// ---- accounts, confirmation, audit -----------------------------------------------------------
let loginShown = false;

function showLogin() {
  if (loginShown) return;
  loginShown = true;
  $("who").hidden = true;
  route();
  $("login-user").focus();
}

function showSession(s) {
  TOKEN = s.token;
  loginShown = false;
  // Without logins the caller is "-": nothing to show, nothing to log out of.
  $("who").hidden = s.user === "-";
  $("who-name").textContent = `${s.user} (${s.role})`;
  route();
}

async function login(e) {
  e.preventDefault();
  const r = await api("/api/login", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ user: $("login-user").value, password: $("login-password").value }),
  });
  $("login-password").value = "";
  if (!r.ok) { $("login-error").textContent = r.error; return; }
  $("login-error").textContent = "";
  showSession(r);
}

async function logout() {
  await post("/api/logout");
  TOKEN = "";
  showLogin();
}

// Open and Close ask first, naming the node and the action: resolves true on Confirm.
function confirmStep(text) {
  const d = $("confirm");
  $("confirm-text").textContent = text;
  return new Promise((resolve) => {
    const done = (yes) => { d.close(); $("confirm-yes").onclick = null; $("confirm-no").onclick = null; resolve(yes); };
    $("confirm-yes").onclick = () => done(true);
    $("confirm-no").onclick = () => done(false);
    d.oncancel = () => done(false);
    d.showModal();
  });
}

async function refreshAudit() {
  const r = await api("/api/audit?limit=200");
  $("audit-error").textContent = r.ok ? "" : r.error;
  if (!r.ok) return;
  const rows = r.entries.map((a) => el("tr", {},
    el("td", { text: new Date(a.unix_ms).toISOString().replace("T", " ").replace("Z", "") }),
    el("td", { text: a.user }), el("td", { text: a.via }), el("td", { text: a.mac === null ? "" : String(a.mac) }),
    el("td", { text: a.what }), el("td", { class: a.result === "ok" ? "" : "err", text: a.result })));
  $("audit-table").tBodies[0].replaceChildren(...rows);
}

// ---- project (scanner/src/ui/project_api.rs, docs/src/plant/projects.md) ----------------------
// The network project of `ui --project FILE` against the network: what was compared, what was not
// and why, every difference. A comparison reads attributes over the bus, so it runs at start, on
// the button and every 15 s while the network view is shown, never two at a time.
let projectBusy = false;
function showProject(r) {
  if (!r || r.project === null) { $("project-card").hidden = true; return false; }
  $("project-card").hidden = false;
  $("project-file").textContent = r.project || "";
  const verdict = $("project-verdict");
  const diffs = r.differences || [];
  verdict.textContent = r.equal ? "equal" : diffs.length ? `${diffs.length} difference(s)` : "not compared";
  verdict.classList.toggle("err", !r.equal);
  const c = r.compared;
  $("project-compared").textContent = (r.ok ? "" : `${r.error} · `) + (c
    ? `compared: ${c.nodes} node(s), ${c.scan_list} scan-list entr${c.scan_list === 1 ? "y" : "ies"}, ${c.identity} identit${c.identity === 1 ? "y" : "ies"}, ${c.configuration} configuration(s) by CCV, ${c.parameters} parameter(s)`
    : "");
  $("project-differences").replaceChildren(
    el("tr", {}, ...["MAC", "what", "project", "network"].map((t) => el("th", { text: t }))),
    ...(diffs.length ? diffs.map((d) => el("tr", { "data-mac": d.mac },
      el("td", { text: String(d.mac) }), el("td", { text: d.what }),
      el("td", { class: "val", text: d.expected }), el("td", { class: "val err", text: d.found })))
      : [el("tr", {}, el("td", { colspan: "4", text: r.ok ? "no differences" : "nothing compared" }))]));
  $("project-not-compared").replaceChildren(...(r.not_compared || []).map((n) => el("li", {
    text: `MAC ${n.mac}: ${n.what} not compared: ${n.why}${n.wanted ? "" : " (as the project asks)"}` })));
  return true;
}
async function compareProject() {
  if (projectBusy) return;
  projectBusy = true;
  try { return showProject(await api("/api/project/compare")); } finally { projectBusy = false; }
}
window.addEventListener("load", async () => {
  $("btn-project").addEventListener("click", compareProject);
  if (await compareProject()) setInterval(() => { if (!$("view-network").hidden) compareProject(); }, 15000);
});

// ---- wiring ----------------------------------------------------------------------------------
// ---- health (scanner/src/health.rs, docs/src/plant/health.md) --------------------------------
function showHealth(h) {
  if (!h || !h.ok) return;
  const b = h.bus;
  const counters = b.tec === null ? "" : ` · TEC ${b.tec} · REC ${b.rec}`;
  const errors = b.error_frames === null ? "" : ` · ${b.error_frames} error frames · ${b.bus_offs} bus-offs`;
  $("health-score").textContent = `score ${h.score}`;
  $("health-bus").textContent = `controller ${b.state}${counters}${errors} · load ${fmtPct(b.load)} · ${b.frames} frames in ${h.duration_s.toFixed(1)} s`;
  $("health-findings").replaceChildren(...(h.findings.length ? h.findings : ["no findings"]).map((f) => el("li", { text: f })));
  const ms = (r) => r ? `${r.min.toFixed(2)} / ${r.avg.toFixed(2)} / ${r.max.toFixed(2)} ms` : "–";
  $("health-nodes").replaceChildren(
    el("tr", {}, ...["MAC", "response min / avg / max", "traffic", "drop-outs", "last drop-out"].map((t) => el("th", { text: t }))),
    ...h.nodes.map((n) => el("tr", { "data-mac": n.mac },
      el("td", { text: String(n.mac) }), el("td", { text: ms(n.response_ms) }),
      el("td", { text: `${n.traffic_pct.toFixed(1)} %` }), el("td", { text: String(n.dropouts) }),
      el("td", { text: n.last_dropout_s === null ? "–" : `${n.last_dropout_s.toFixed(1)} s` }))));
}

async function refreshHealth() {
  if ($("view-network").hidden) return;
  showHealth(await api("/api/health"));
}

// ---- events (scanner/src/events.rs, docs/src/plant/scanner.md) --------------------------------
// The newest events first, at most 50 rows; each poll asks only for those after the last seen.
let eventsSeen = 0;
const eventRows = [];
function showEvents(r) {
  if (!r || !r.ok || !r.events.length) return;
  for (const e of r.events) {
    if (e.seq <= eventsSeen) continue;
    eventsSeen = e.seq;
    eventRows.unshift(el("tr", { "data-kind": e.kind, "data-mac": e.mac },
      el("td", { text: `${(e.time_us / 1e6).toFixed(3)} s` }), el("td", { text: `MAC ${e.mac}` }),
      el("td", { text: e.kind }), el("td", { text: e.detail })));
  }
  eventRows.splice(50);
  $("events").replaceChildren(el("tr", {}, ...["time", "MAC", "kind", "detail"].map((t) => el("th", { text: t }))), ...eventRows);
}

let eventsBusy = false;
async function refreshEvents() {
  if (eventsBusy) return;
  eventsBusy = true;
  try { showEvents(await api(`/api/events?since=${eventsSeen}`)); } finally { eventsBusy = false; }
}

// ---- serial line (scanner/src/ui/serial_trace_api.rs, docs/src/plant/console.md) --------------
// The converter's line trace, polled while the panel is open: each poll asks for the lines after
// the last one shown, so nothing new costs the device one Read_Trace. Newest first, at most 300 rows.
const SERIAL_ROWS = 300;
let serialOpen = false, serialSeen = 0, serialBusy = false;
function serialReset() {
  serialOpen = false; serialSeen = 0;
  $("serial-table").tBodies[0].replaceChildren();
  $("serial-wrap").hidden = true;
  $("serial-profile").hidden = true;
  $("serial-note").textContent = ""; $("serial-note").className = "outcome";
  $("btn-serial").textContent = "Open";
}
function serialToggle() {
  const open = !serialOpen;
  serialReset();
  serialOpen = open;
  $("btn-serial").textContent = open ? "Close" : "Open";
  if (open) { $("serial-note").textContent = "reading…"; refreshSerial(); }
}
const SERIAL_ERROR = /^(not a |incomplete frame|bytes outside)/;
function showSerial(r) {
  const note = $("serial-note");
  if (!r.ok) { note.className = "outcome err"; note.textContent = r.error; return; }
  if (!r.converter) { note.className = "outcome"; note.textContent = r.note; $("serial-wrap").hidden = true; return; }
  $("serial-wrap").hidden = false;
  $("serial-profile").hidden = false;
  $("serial-profile").textContent = r.profile;
  note.className = "outcome";
  note.textContent = `${r.entries} entries read` + (r.missed ? ` · ${r.missed} entries missed (the ring overran)` : "")
    + (r.dropped ? ` · ${r.dropped} lines no longer kept by the console` : "");
  const body = $("serial-table").tBodies[0];
  for (const l of r.lines) {
    if (l.n <= serialSeen) continue;
    serialSeen = l.n;
    const bytes = l.kind === "tx" || l.kind === "rx";
    const cls = l.kind === "missed" || l.kind.endsWith(" err") || l.kind.startsWith("uart") || SERIAL_ERROR.test(l.decoded) ? "line-error"
      : bytes ? "" : "line-event";
    body.prepend(el("tr", { "data-kind": l.kind, "data-n": l.n, class: cls },
      el("td", { text: l.kind === "missed" || l.kind === "restart" ? "" : `#${l.seq}` }), el("td", { text: String(l.time_ms) }),
      el("td", { text: l.kind }), el("td", { class: "meaning", text: l.decoded }), el("td", { class: "bytes", text: l.hex })));
  }
  while (body.rows.length > SERIAL_ROWS) body.deleteRow(-1);
  if (r.next < serialSeen) serialSeen = r.next;
}
async function refreshSerial() {
  if (!serialOpen || serialBusy || currentMac === null || $("view-device").hidden) return;
  serialBusy = true;
  const mac = currentMac;
  try {
    const r = await api(`/api/node/${mac}/serial-trace?since=${serialSeen}`);
    if (serialOpen && mac === currentMac) showSerial(r);
  } finally { serialBusy = false; }
}

function init() {
  $("btn-health-clear").addEventListener("click", async () => showHealth(await post("/api/health/clear")));
  $("login-form").addEventListener("submit", login);
  $("btn-logout").addEventListener("click", logout);
  $("btn-audit").addEventListener("click", refreshAudit);
  buildGrid();
  $("btn-open").addEventListener("click", () => breakerCommand("open"));
  $("btn-close").addEventListener("click", () => breakerCommand("close"));
  $("param-form").addEventListener("submit", (e) => {
    e.preventDefault();
    breakerCommand("param", { id: Number($("param-id").value), value: Number($("param-value").value) });
  });
  $("explicit-form").addEventListener("submit", (e) => { e.preventDefault(); explicit(e.submitter ? e.submitter.dataset.op : "get"); });
  $("btn-params").addEventListener("click", readParams);
  $("btn-serial").addEventListener("click", serialToggle);
  $("export-csv").addEventListener("click", () => {
    const now = Date.now();
    $("export-csv").href = netPath(`/api/export.csv?mac=${currentMac}&from=${now - 3600e3}&to=${now + 1000}`);
  });
  $("rec-start").addEventListener("click", () => recordCommand("start", "recording to"));
  $("rec-stop").addEventListener("click", () => recordCommand("stop", "recorded"));
  api("/api/session").then((s) => s.ok && showSession(s));
  api("/api/record").then((r) => r.recording && showRecord(r, "recording to"));
  route();
  refreshState();
  setInterval(refreshState, 500);
  setInterval(() => { if (!$("view-device").hidden) refreshNode(); }, 250);
  setInterval(refreshPlot, 1000);
  setInterval(refreshTrace, 300);
  setInterval(refreshSerial, 500);
  refreshHealth();
  setInterval(refreshHealth, 2000);
  refreshEvents();
  setInterval(refreshEvents, 1000);
  setInterval(async () => {
    if ($("rec-stop").disabled || recordBusy) return;
    const seq = recordSeq;
    const r = await api("/api/record");
    if (seq === recordSeq) showRecord(r, r.recording ? "recording to" : undefined);
  }, 1000);
}
init();
