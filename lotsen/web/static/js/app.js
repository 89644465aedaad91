// lotsen operator interface: connection to the boat, route editor, operation, monitoring.
import { RouteModel } from "./route.js";
import { MapView } from "./map.js";
import { StripChart } from "./plot.js";
import { KeyboardDriver } from "./keys.js";

const $ = (sel) => document.querySelector(sel);
const $$ = (sel) => Array.from(document.querySelectorAll(sel));

const state = {
  ws: null, connected: false, pilot: false, token: null, hello: null,
  telemetry: null, lastPlan: null, planSeq: 0, planTimer: null, nextId: 1, pending: new Map(),
  rttMs: null, framesRx: 0, mode: null, logs: [],
};
window.lotsen = state;   // for debugging and the browser tests

const route = new RouteModel();
const map = new MapView($("#map"), route, {
  defaultSpeed: () => Number($("#default-speed").value) || 0.5,
  onSelect: () => renderTable(),
  onInfo: ([n, e]) => { $("#mapinfo").textContent = `N ${n.toFixed(2)} m  E ${e.toFixed(2)} m  ·  ${map.scale.toFixed(1)} px/m`; },
  onPan: () => { $("#follow").checked = false; },
  onPolygonDone: () => setTool("select"),
});
state.map = map; state.route = route;

// -- connection -------------------------------------------------------------------------------
function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const ws = new WebSocket(`${proto}//${location.host}/ws`);
  state.ws = ws;
  ws.onopen = () => {
    state.connected = true; setConn();
    if (state.token) send({ type: "auth", token: state.token });   // re-take the seat after a reconnect
  };
  ws.onclose = () => {
    state.connected = false; state.pilot = false; setConn(); setRole();
    setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => { try { onMessage(JSON.parse(ev.data)); } catch (e) { console.error(e); } };
}

function send(msg) {
  if (!state.ws || state.ws.readyState !== WebSocket.OPEN) return null;
  msg.id = state.nextId++;
  state.ws.send(JSON.stringify(msg));
  return msg.id;
}

function request(msg) {   // a message whose reply we wait for
  return new Promise((resolve) => {
    const id = send(msg);
    if (id === null) { resolve({ type: "error", error: "not connected" }); return; }
    state.pending.set(id, resolve);
  });
}

setInterval(() => {   // liveness of the pilot (and round-trip time for everyone)
  if (state.connected) send({ type: "ping", t: performance.now() });
}, 250);

function onMessage(m) {
  if (m.id != null && state.pending.has(m.id)) {   // a reply to request(): the caller handles it
    const resolve = state.pending.get(m.id); state.pending.delete(m.id); resolve(m); return;
  }
  switch (m.type) {
    case "telemetry": onTelemetry(m); break;
    case "hello": state.hello = m; break;
    case "pong": if (m.t != null) state.rttMs = performance.now() - m.t; break;
    case "auth_ok": state.pilot = true; setRole(); toast("you are the pilot"); break;
    case "pilot": state.pilot = !!m.pilot; if (!m.pilot && m.reason !== "released") { state.token = null; } setRole(); toast(`controls released: ${m.reason}`, !m.pilot && m.reason !== "released"); break;
    case "path": map.activePath = m; map.invalidate(); break;
    case "active_route": state.activeRoute = m.route; if (!route.complete() && m.route) route.fromDict(m.route); break;
    case "log": onLog(m); break;
    case "magcal": onMagcal(m); break;
    case "ack": toast(`sent: ${m.action}`); break;
    case "error": onError(m); break;
  }
}

function onError(m) {
  if (m.code === "pilot_busy") {
    $("#btn-takeover").hidden = !/silent/.test(m.error);
  }
  if (m.code === "bad_token") state.token = null;
  toast(m.error, true);
}

// -- telemetry --------------------------------------------------------------------------------
const plots = {
  xte: new StripChart($("#plot-xte"), [{ label: "xte", color: "#ff8c2e" }], { title: "cross-track", unit: "m", minSpan: 0.4 }),
  speed: new StripChart($("#plot-speed"), [{ label: "speed", color: "#ffd84a" }, { label: "ref", color: "#38c172", dash: [5, 3] }], { title: "speed", unit: "m/s", minSpan: 0.4 }),
  heading: new StripChart($("#plot-heading"), [{ label: "heading", color: "#3fa7ff" }, { label: "error", color: "#ef4c4c" }], { title: "heading", unit: "deg", minSpan: 20 }),
  props: new StripChart($("#plot-props"), [{ label: "n1", color: "#ffd84a" }, { label: "n2", color: "#38c172" }, { label: "nt", color: "#c58bff" }, { label: "achieved", color: "#93a1b0", dash: [3, 3] }], { title: "propellers", unit: "rev/s", minSpan: 10 }),
  az: new StripChart($("#plot-az"), [{ label: "α1", color: "#ffd84a" }, { label: "α2", color: "#38c172" }], { title: "azimuths", unit: "deg", minSpan: 20 }),
};
const DEG = 180 / Math.PI;

function onTelemetry(f) {
  state.telemetry = f; state.framesRx++;
  const p = f.pose, c = f.ctrl, cmd = f.cmd || f.act;
  if (p) map.setBoat(p, f.truth);
  if (c) { map.predicted = c.pred_n && c.pred_n.length ? { n: c.pred_n, e: c.pred_e } : null; }
  plots.xte.push(f.t, [c ? c.xte : null]);
  const speed = p ? Math.hypot(p.u, p.v) : null;
  plots.speed.push(f.t, [speed, c ? c.speed_ref : null]);
  plots.heading.push(f.t, [p ? wrap180(p.psi * DEG) : null, c && c.hdg_err != null ? c.hdg_err * DEG : null]);
  plots.props.push(f.t, [cmd ? cmd.n1 : null, cmd ? cmd.n2 : null, cmd ? cmd.nt : null, f.act && f.cmd ? (f.act.n1 + f.act.n2) / 2 : null]);
  plots.az.push(f.t, [cmd ? cmd.a1 * DEG : null, cmd ? cmd.a2 * DEG : null]);
  renderStatus(f);
}
function wrap180(d) { return ((d + 180) % 360 + 360) % 360 - 180; }
setInterval(() => Object.values(plots).forEach(p => p.draw()), 100);

function renderStatus(f) {
  const s = f.sup;
  state.mode = s ? s.mode : null;
  const mode = s ? `${s.mode}${s.armed ? " (armed)" : ""}${s.reason ? " — " + s.reason : ""}` : "no supervisor";
  $("#st-mode").textContent = mode;
  const mb = $("#mode");
  mb.textContent = `mode: ${s ? s.mode : "?"}`;
  mb.className = "badge " + (!s ? "" : /estop|fail/i.test(s.mode) ? "bad" : /manual|hold/i.test(s.mode) ? "warn" : "ok");
  $("#estop").classList.toggle("latched", !!(s && /estop/i.test(s.mode)));
  const g = f.gnss;
  $("#st-gnss").textContent = g ? `${g.fix} · ±${g.h_acc != null ? g.h_acc.toFixed(3) : "?"} m · ${g.sv} sats` : "-";
  const b = f.bat;
  $("#st-bat").textContent = b ? `${b.v != null ? b.v.toFixed(2) : "?"} V${b.frac != null ? " · " + Math.round(b.frac * 100) + " %" : ""}` : "-";
  const l = f.link;
  $("#st-link").textContent = `${state.pilot ? "you are the pilot" : l.pilot ? "pilot connected" : "no pilot"} · ${l.clients} client(s)` +
    (state.rttMs != null ? ` · rtt ${state.rttMs.toFixed(0)} ms` : "");
  const c = f.ctrl;
  $("#st-ctrl").textContent = c ? `${c.controller} ${c.status} · solve ${c.solve_ms != null ? c.solve_ms.toFixed(1) : "?"} ms · xte ${c.xte != null ? c.xte.toFixed(2) : "?"} m` : "-";
  const p = f.pose;
  $("#st-pose").textContent = p ? `N ${p.n.toFixed(2)} E ${p.e.toFixed(2)} · ${wrap360(p.psi * DEG).toFixed(0)}° · ${Math.hypot(p.u, p.v).toFixed(2)} m/s (${p.src || "?"})` : "-";
  const warn = [...(s ? s.warnings : []), ...(s ? s.failsafes.map(x => "failsafe: " + x) : []), ...(f.rc && f.rc.active ? ["RC override active"] : [])];
  if (g && g.fix !== "RTK_FIXED") warn.push(`GNSS ${g.fix}`);
  const ul = $("#warnings");
  const html = warn.map(w => `<li>${esc(w)}</li>`).join("");
  if (ul.innerHTML !== html) ul.innerHTML = html;
}
function wrap360(d) { return ((d % 360) + 360) % 360; }

function onLog(m) {
  state.logs.push(m);
  if (state.logs.length > 300) state.logs.shift();
  const li = document.createElement("li");
  li.className = m.level;
  li.textContent = `${m.t != null ? m.t.toFixed(1) : ""} ${m.source}: ${m.text}`;
  const ul = $("#log");
  ul.prepend(li);
  while (ul.children.length > 200) ul.lastChild.remove();
}

function onMagcal(m) {   // MagCalibrationResult of the one-turn manoeuvre
  const box = $("#magcal");
  box.hidden = false;
  const f = (x, d = 3) => (x == null ? "?" : x.toFixed(d));
  box.textContent = m.ok
    ? `magnetometer calibration: ${m.text}\nhard iron (centre) ${m.center.map(x => f(x, 2)).join(", ")}\n` +
      `soft iron [${m.matrix.map(r => r.map(x => f(x, 4)).join(" ")).join("; ")}]\n` +
      `residual ${f(m.residual, 4)} · coverage ${f(m.coverage_deg, 0)}°`
    : `magnetometer calibration failed: ${m.text}`;
  box.style.borderLeftColor = m.ok ? "#38c172" : "#ef4c4c";
  toast(m.ok ? "magnetometer calibrated" : `magnetometer calibration failed: ${m.text}`, !m.ok);
}

// -- roles ------------------------------------------------------------------------------------
function setConn() {
  const c = $("#conn");
  c.textContent = state.connected ? "connected" : "offline — reconnecting";
  c.className = "badge " + (state.connected ? "ok" : "bad");
}

function setRole() {
  $("#role").textContent = state.pilot ? "pilot" : "viewer";
  $("#role").className = "badge " + (state.pilot ? "ok" : "");
  $("#btn-auth").hidden = state.pilot; $("#token").hidden = state.pilot;
  $("#btn-release").hidden = !state.pilot;
  if (state.pilot) $("#btn-takeover").hidden = true;
  $$("[data-action]").forEach(b => { if (b.id !== "estop") b.disabled = !state.pilot; });
  $("#btn-use").disabled = !state.pilot;
}

function authenticate(takeover) {
  const token = $("#token").value.trim() || state.token;
  if (!token) { toast("enter the pilot token (printed by `lotsen run`)", true); return; }
  state.token = token;
  $("#token").value = "";
  const msg = { type: "auth", token };
  if (takeover) msg.takeover = true;
  send(msg);
}
$("#btn-auth").onclick = () => authenticate(false);
$("#token").addEventListener("keydown", ev => { if (ev.key === "Enter") authenticate(false); });
$("#btn-takeover").onclick = () => authenticate(true);
$("#btn-release").onclick = () => { driver.stop(); send({ type: "release" }); state.token = null; };

// -- operator commands -------------------------------------------------------------------------
function command(action) {
  if (!state.pilot) { toast(`${action}: take the controls first (pilot token)`, true); return; }
  send({ type: "command", action });
}
$$("[data-action]").forEach(b => b.addEventListener("click", () => {
  if (b.dataset.action === "estop") driver.stop();
  command(b.dataset.action);
}));

// -- keyboard driving --------------------------------------------------------------------------
const driver = new KeyboardDriver({
  send: (c) => send({ type: "manual", surge: round3(c.surge), sway: round3(c.sway), yaw: round3(c.yaw) }),
  enabled: () => state.pilot && state.connected,
  gain: () => Number($("#gain").value),
  onChange: (keys, c, hint) => {
    $$("#keys span").forEach(s => s.classList.toggle("on", keys.has(s.dataset.key)));
    $("#manualcmd").textContent = `surge ${c.surge.toFixed(2)} · sway ${c.sway.toFixed(2)} · yaw ${c.yaw.toFixed(2)}`;
    if (hint) toast(hint, true);
  },
  onEstop: () => command("estop"),
});
state.driver = driver;
$("#gain").addEventListener("input", () => { $("#gainval").textContent = Number($("#gain").value).toFixed(2); });
function round3(x) { return Math.round(x * 1000) / 1000; }

// -- route editing and planning ------------------------------------------------------------------
function setTool(tool) {
  map.setTool(tool);
  $$("#maptools .tool").forEach(b => b.classList.toggle("active", b.dataset.tool === tool));
  $("#btn-finish").hidden = !(tool === "area" || tool === "obstacle");
}
$$("#maptools .tool").forEach(b => b.addEventListener("click", () => setTool(b.dataset.tool)));
$("#btn-finish").onclick = () => { if (!route.finishPolygon()) toast("a polygon needs at least 3 corners", true); setTool("select"); };
$("#btn-fit").onclick = () => map.fit();
$("#follow").onchange = (ev) => { map.follow = ev.target.checked; };
window.addEventListener("keydown", ev => {
  if (ev.target.tagName === "INPUT") return;
  if (ev.key === "Enter" && route.drawing) { route.finishPolygon(); setTool("select"); }
  if ((ev.key === "Delete" || ev.key === "Backspace") && route.selected && route.selected.kind === "node") route.deleteNode(route.selected.index);
});

route.onChange((replan) => {
  renderTable();
  map.invalidate();
  if (replan) schedulePlan();
});

function schedulePlan() {
  clearTimeout(state.planTimer);
  state.planTimer = setTimeout(plan, 150);
}

async function plan() {
  if (!route.complete()) {
    route.errors = []; map.draftPath = null; state.lastPlan = null;
    setPlanStatus(route.harbour ? "add at least one route node" : "place the harbour node (Harbour tool), then route nodes", "");
    map.invalidate(); renderTable(); return;
  }
  const seq = ++state.planSeq;
  const res = await request({ type: "plan", route: route.toDict() });
  if (seq !== state.planSeq) return;   // a newer edit is being planned
  state.lastPlan = res;
  if (res.type === "plan_result" && res.ok) {
    route.errors = [];
    map.draftPath = res.path;
    const detours = res.segments.filter(s => s.detour).length;
    setPlanStatus(`planned: ${res.length_m.toFixed(1)} m, about ${fmtDuration(res.duration_s)}` + (detours ? `, ${detours} detour part(s)` : ""), "ok");
  } else {
    route.errors = res.errors || [{ kind: "route", message: res.error || "planning failed" }];
    map.draftPath = null;
    setPlanStatus(route.errors.map(e => e.message).join("\n"), "bad");
  }
  map.invalidate(); renderTable();
}

function setPlanStatus(text, cls) {
  const el = $("#planstatus");
  el.textContent = text; el.className = "planstatus " + cls;
}
function fmtDuration(s) { return s >= 60 ? `${Math.floor(s / 60)} min ${Math.round(s % 60)} s` : `${Math.round(s)} s`; }

function renderTable() {
  const tb = $("#nodetable tbody");
  const rows = [];
  const sel = route.selected;
  const row = (label, p, kind, i) => {
    const err = route.errorFor(kind, i);
    const isSel = sel && sel.kind === kind && (kind === "harbour" || sel.index === i);
    const speed = kind === "harbour" ? `<td class="dim">0</td>` : `<td><input data-f="speed_mps" type="number" step="0.1" min="0" value="${p.speed_mps}"></td>`;
    rows.push(`<tr data-kind="${kind}" data-i="${i ?? ""}" class="${isSel ? "selected" : ""} ${err ? "err" : ""}">` +
      `<td>${label}</td><td><input data-f="north" type="number" step="0.5" value="${p.north}"></td>` +
      `<td><input data-f="east" type="number" step="0.5" value="${p.east}"></td>` +
      `<td><input data-f="heading_deg" type="number" step="5" value="${p.heading_deg}"></td>${speed}` +
      `<td>${kind === "node" ? `<button type="button" data-del="${i}" title="delete node">✕</button>` : ""}</td></tr>`);
    if (err) rows.push(`<tr class="err"><td></td><td colspan="5" class="errmsg">${esc(err.message)}</td></tr>`);
  };
  if (route.harbour) row("H", route.harbour, "harbour");
  route.nodes.forEach((n, i) => row(String(i), n, "node", i));
  const html = rows.join("");
  // keep the table while the user is typing in it (re-render would steal the focus)
  if (!tb.contains(document.activeElement) && tb.innerHTML !== html) tb.innerHTML = html;
  const polys = [];
  if (route.area) polys.push(`<div class="${route.errorFor("area") ? "err" : ""}">navigable area, ${route.area.length} corners <button type="button" data-delpoly="area">✕</button></div>`);
  route.obstacles.forEach((o, i) => polys.push(`<div class="${route.errorFor("obstacle", i) ? "err" : ""}">obstacle ${i}, ${o.polygon.length} corners, forbidden ` +
    `<select data-forbid="${i}"><option ${o.forbidden === "inside" ? "selected" : ""}>inside</option><option ${o.forbidden === "outside" ? "selected" : ""}>outside</option></select>` +
    ` <button type="button" data-delpoly="${i}">✕</button></div>`));
  $("#polylist").innerHTML = polys.join("");
}

$("#nodetable").addEventListener("change", ev => {
  const inp = ev.target, tr = inp.closest("tr");
  if (!inp.dataset.f || !tr) return;
  const p = tr.dataset.kind === "harbour" ? route.harbour : route.nodes[Number(tr.dataset.i)];
  const v = Number(inp.value);
  if (!p || !isFinite(v)) return;
  p[inp.dataset.f] = v;
  inp.blur();
  route.changed();
});
$("#nodetable").addEventListener("click", ev => {
  const del = ev.target.dataset && ev.target.dataset.del;
  if (del !== undefined) { route.deleteNode(Number(del)); return; }
  const tr = ev.target.closest("tr[data-kind]");
  if (tr) { route.selected = tr.dataset.kind === "harbour" ? { kind: "harbour" } : { kind: "node", index: Number(tr.dataset.i) }; map.invalidate(); }
});
$("#polylist").addEventListener("click", ev => {
  const d = ev.target.dataset && ev.target.dataset.delpoly;
  if (d === undefined) return;
  if (d === "area") route.area = null; else route.obstacles.splice(Number(d), 1);
  route.changed();
});
$("#polylist").addEventListener("change", ev => {
  const i = ev.target.dataset && ev.target.dataset.forbid;
  if (i === undefined) return;
  route.obstacles[Number(i)].forbidden = ev.target.value;
  route.changed();
});

$("#btn-clear").onclick = () => { if (confirm("Clear the route?")) route.clear(); };

$("#btn-use").onclick = async () => {
  if (!route.complete()) { toast("the route needs a harbour and at least one node", true); return; }
  const res = await request({ type: "route", route: route.toDict() });
  if (res.type === "route_ok") toast(`route sent to the boat (${res.length_m.toFixed(1)} m)`);
  else { toast(res.error || "route refused", true); if (res.errors) { route.errors = res.errors; renderTable(); map.invalidate(); } }
};

async function save(format) {
  if (!route.complete()) { toast("nothing to save: place the harbour and nodes", true); return; }
  const res = await request({ type: "export", format, route: route.toDict() });
  if (res.type !== "export_result") { toast(res.error, true); return; }
  const blob = new Blob([res.text], { type: format === "yaml" ? "application/x-yaml" : "application/geo+json" });
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob);
  a.download = `route.${format === "yaml" ? "yaml" : "geojson"}`;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}
$("#btn-save-yaml").onclick = () => save("yaml");
$("#btn-save-geojson").onclick = () => save("geojson");

$("#file-load").addEventListener("change", async ev => {
  const file = ev.target.files[0];
  ev.target.value = "";
  if (!file) return;
  const text = await file.text();
  const format = /\.(geo)?json$/i.test(file.name) ? "geojson" : "yaml";
  const res = await request({ type: "import", format, text });
  if (res.type === "import_result") { route.fromDict(res.route); map.fit(); toast(`loaded ${file.name}`); }
  else toast(res.error, true);
});

// -- tabs, toasts -------------------------------------------------------------------------------
$$("#tabs .tab").forEach(b => b.addEventListener("click", () => {
  $$("#tabs .tab").forEach(x => x.classList.toggle("active", x === b));
  $$(".tabpanel").forEach(p => { p.hidden = p.id !== `tab-${b.dataset.tab}`; });
}));

let toastTimer = null;
function toast(text, bad = false) {
  const t = $("#toast");
  t.textContent = text; t.className = "show" + (bad ? " bad" : "");
  clearTimeout(toastTimer);
  toastTimer = setTimeout(() => { t.className = ""; }, bad ? 4000 : 2000);
}
function esc(s) { return String(s).replace(/[&<>"']/g, c => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]); }

setRole(); setConn(); renderTable(); plan();
connect();
map.fit();
