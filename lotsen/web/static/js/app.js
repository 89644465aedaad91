// lotsen operator interface: connection to the boat, HUD and alerts, route editor with undo,
// upload with read-back, operation (arm, modes, keyboard), offline map tiles, logs.
import { RouteModel, parseField, routeDiff, LIMITS } from "./route.js";
import { MapView } from "./map.js";
import { StripChart } from "./plot.js";
import { KeyboardDriver, PERIOD_MS } from "./keys.js";
import { AlertCenter, esc } from "./alerts.js";
import { TileLayer } from "./tiles.js";
import { fmtLatLon, latLonToNe, neToLatLon, tilesForBox } from "./geo.js";

const $ = (sel) => document.querySelector(sel);
const $$ = (sel) => Array.from(document.querySelectorAll(sel));
const DEG = 180 / Math.PI;
const MOVING = ["AUTO", "RETURN"];
const EDIT_TOL = 2e-3;   // the editor keeps 1 mm / 0.001 deg: closer than this is the same route

const state = {
  ws: null, connected: false, pilot: false, token: null, hello: null,
  telemetry: null, lastPlan: null, planSeq: 0, planTimer: null, nextId: 1, pending: new Map(),
  rttMs: null, framesRx: 0, mode: null, logs: [], origin: null,
  boatRoute: null,        // the boat's read-back {route, route_id}
  upload: null,           // this page's last upload {route_id, route}
  uploadedId: null,       // the last upload seen on the bus (any page)
  viewTouched: false, fits: 0, tilesIndex: null, tileProgress: null, logList: [], lastRequest: null,
};
window.lotsen = state;   // for debugging and the browser tests

const route = new RouteModel();
const tiles = new TileLayer(() => map.invalidate());
const map = new MapView($("#map"), route, {
  defaultSpeed: () => Number($("#default-speed").value) || 0.5,
  onSelect: () => renderTable(),
  onInfo: ([n, e]) => {
    const ll = state.origin ? ` · ${fmtLatLon(...neToLatLon(n, e, state.origin))}` : "";
    $("#mapinfo").textContent = `N ${n.toFixed(2)} m  E ${e.toFixed(2)} m${ll}  ·  ${map.scale.toFixed(1)} px/m`;
  },
  onPan: () => { $("#follow").checked = false; state.viewTouched = true; },
  onPolygonDone: () => setTool("select"),
  onEdit: () => renderTable(),
});
map.tiles = tiles;
state.map = map; state.route = route; state.tiles = tiles; state.send = (msg) => send(msg);
$("#map").addEventListener("wheel", () => { state.viewTouched = true; });
$("#map").addEventListener("pointerdown", () => { state.viewTouched = true; });

const alerts = new AlertCenter($("#alerts"), { onChange: () => renderNext() });
state.alerts = alerts;

// -- connection -------------------------------------------------------------------------------
function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const ws = new WebSocket(`${proto}//${location.host}/ws`);
  state.ws = ws;
  ws.onopen = () => {
    state.connected = true; setConn();
    if (state.token) send({ type: "auth", token: state.token });   // (re-)take the seat at once
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
    if (id === null) { resolve({ type: "error", error: "not connected to the boat" }); return; }
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
    case "hello": onHello(m); break;
    case "pong": if (m.t != null) state.rttMs = performance.now() - m.t; break;
    case "auth_ok": state.pilot = true; setRole(); toast("you are the pilot"); schedulePlan(); break;
    case "pilot":
      state.pilot = !!m.pilot;
      if (!m.pilot && m.reason !== "released") { state.token = null; alerts.push({ severity: "error", code: "web:seat", text: `controls lost: ${m.reason}` }); }
      setRole(); if (m.reason === "released") toast("controls released"); break;
    case "path": map.activePath = m; map.invalidate(); maybeFit(); break;
    case "active_route": onReadback(m); break;
    case "uploaded": state.uploadedId = m.route_id; renderReadback(); break;
    case "alert": onAlert(m); break;
    case "log": onLog(m); break;
    case "magcal": onMagcal(m); break;
    case "ack": state.lastRequest = { action: m.action, t: performance.now() }; toast(`requested: ${m.action} (waiting for the boat)`); break;
    case "tiles_progress": onTileProgress(m); break;
    case "evicted": alerts.push({ severity: "warning", code: "web:evicted", text: `disconnected by the boat's server: ${m.reason}; reconnecting` }); break;
    case "error": onError(m); break;
  }
}

function onHello(m) {
  state.hello = m;
  state.origin = m.origin;
  map.origin = m.origin;
  if (m.uploaded_route_id) state.uploadedId = m.uploaded_route_id;
  $("#originbox").textContent = m.origin
    ? `local origin ${fmtLatLon(m.origin.lat, m.origin.lon)}, ${m.origin.h} m; lat/lon from local metres with WGS84 (the server's formulas, < 1 mm apart); tiles placed on Web Mercator`
    : "no geographic origin (set `origin` in the launch config): local metres only, no map background";
  refreshTiles();
  renderMaps();
  refreshRecording();
}

function onError(m) {
  if (m.code === "pilot_busy") $("#btn-takeover").hidden = !/silent/.test(m.error);
  if (m.code === "bad_token") state.token = null;
  const sev = ["rate_limited", "busy"].includes(m.code) ? "warning" : "error";
  alerts.push({ severity: sev, code: `web:${m.code}`, text: m.error });
}

function onAlert(m) {
  let a = { ...m };
  // a refused request is an error for the operator who asked, whatever the core's severity
  if (a.code && a.code.startsWith("refused:") && (a.severity === "info" || a.severity === "warning")) a.severity = "error";
  // "link lost" before any pilot ever connected is the normal start, not a warning
  const ever = (state.telemetry && state.telemetry.link && state.telemetry.link.ever) || (state.hello && state.hello.pilot_ever);
  if (a.code === "failsafe:link_lost" && !ever && a.active !== false) a = { ...a, severity: "info", text: "no pilot has taken the controls yet: the boat does not move by itself" };
  alerts.push(a);
  onLog({ t: m.t, level: a.severity, source: m.source || "alert", text: `${a.active === false ? "cleared: " : ""}${m.text}` });
}

// -- telemetry --------------------------------------------------------------------------------
const plots = {
  xte: new StripChart($("#plot-xte"), [{ label: "xte", color: "#ff8c2e" }], { title: "cross-track error", unit: "m", minSpan: 0.1 }),
  speed: new StripChart($("#plot-speed"), [{ label: "SOG", color: "#ffd84a" }, { label: "ref", color: "#3fa7ff", dash: [4, 3] }], { title: "speed", unit: "m/s", minSpan: 0.2 }),
  heading: new StripChart($("#plot-heading"), [{ label: "heading", color: "#ffd84a" }, { label: "error", color: "#ff8c2e" }], { title: "heading", unit: "deg", minSpan: 10 }),
  props: new StripChart($("#plot-props"), [{ label: "n1", color: "#ffd84a" }, { label: "n2", color: "#38c172" }, { label: "bow", color: "#c58bff" }, { label: "meas", color: "#ffffff", dash: [2, 3] }], { title: "propellers", unit: "rev/s", minSpan: 10 }),
  az: new StripChart($("#plot-az"), [{ label: "α1", color: "#ffd84a" }, { label: "α2", color: "#38c172" }], { title: "azimuths", unit: "deg", minSpan: 20 }),
};
state.plots = plots;
$("#plotwin").addEventListener("change", ev => { Object.values(plots).forEach(p => { p.windowS = Number(ev.target.value); }); });

function onTelemetry(f) {
  state.telemetry = f; state.framesRx++;
  const p = f.pose, c = f.ctrl, cmd = f.cmd || f.act;
  if (p) map.setBoat(p, f.truth);
  map.predicted = c && c.pred_n && c.pred_n.length ? { n: c.pred_n, e: c.pred_e } : null;
  plots.xte.push(f.t, [c ? c.xte : null]);
  const speed = p ? Math.hypot(p.u, p.v) : null;
  plots.speed.push(f.t, [speed, c ? c.speed_ref : null]);
  plots.heading.push(f.t, [p ? wrap180(p.psi * DEG) : null, c && c.hdg_err != null ? c.hdg_err * DEG : null]);
  plots.props.push(f.t, [cmd ? cmd.n1 : null, cmd ? cmd.n2 : null, cmd ? cmd.nt : null, f.act && f.cmd ? (f.act.n1 + f.act.n2) / 2 : null]);
  plots.az.push(f.t, [cmd ? cmd.a1 * DEG : null, cmd ? cmd.a2 * DEG : null]);
  state.mode = f.sup ? f.sup.mode : null;
  renderHud(f);
  updateButtons();
  renderNext();
  maybeFit();
}
function wrap180(d) { return ((d + 180) % 360 + 360) % 360 - 180; }
function wrap360(d) { return ((d % 360) + 360) % 360; }
setInterval(() => Object.values(plots).forEach(p => p.draw()), 100);

// first screen: the boat and its route in view, until the operator moves the map
function maybeFit() {
  if (state.viewTouched || state.fits >= 3 || !map.boat) return;
  const key = `${!!map.activePath}|${route.complete()}`;
  if (state.fitKey === key) return;
  state.fitKey = key; state.fits++;
  if (route.complete() || map.activePath) map.fit();
  else map.fitPoints([[map.boat.n, map.boat.e]], 40);
}

function fmtDuration(s) {
  if (s == null || !isFinite(s)) return "?";
  s = Math.round(s);
  if (s >= 3600) return `${Math.floor(s / 3600)} h ${Math.round((s % 3600) / 60)} min`;
  return s >= 60 ? `${Math.floor(s / 60)} min ${s % 60} s` : `${s} s`;
}
function setV(sel, text, cls = "") { const el = $(sel); el.textContent = text; el.className = "v " + cls; }

function renderHud(f) {
  const s = f.sup, p = f.pose, c = f.ctrl, g = f.gnss, b = f.bat, pr = f.prog, l = f.link;
  const mb = $("#mode");
  mb.textContent = `mode: ${s ? s.mode : "?"}`;
  mb.className = "badge big " + (!s ? "" : /ESTOP|FAIL/.test(s.mode) ? "bad" : /MANUAL|HOLD|RC/.test(s.mode) ? "warn" : "ok");
  const ab = $("#armed");
  ab.textContent = s ? `${s.armed ? "ARMED" : "disarmed"} · ESCs ${s.escs_armed ? "ready" : "not ready"}` : "arming: ?";
  ab.className = "badge " + (s && s.armed ? "armed" : "");
  $("#estop").classList.toggle("latched", !!(s && s.mode === "ESTOP"));
  setV("#hud-mode", s ? `${s.mode}${s.reason ? " — " + s.reason : ""}` : "no supervisor", !s ? "" : s.mode === "ESTOP" ? "bad" : "");
  const sog = p ? Math.hypot(p.u, p.v) : null;
  setV("#hud-speed", sog == null ? "-" : `${sog.toFixed(2)} m/s${c && c.speed_ref != null ? ` (ref ${c.speed_ref.toFixed(2)})` : ""}`);
  setV("#hud-heading", p ? `${wrap360(p.psi * DEG).toFixed(0)}°` : "-");
  if (g) {
    const cls = g.fix === "RTK_FIXED" ? "ok" : g.fix === "RTK_FLOAT" ? "warn" : "bad";
    setV("#hud-gnss", `${g.fix} ±${g.h_acc != null ? g.h_acc.toFixed(3) : "?"} m · ${g.sv} sats · corr ${g.corr_age != null ? g.corr_age.toFixed(1) + " s" : "-"}`, cls);
  } else setV("#hud-gnss", "-");
  if (b) {
    const left = b.left_s != null ? ` · ${fmtDuration(b.left_s)} left` : "";
    const cls = b.frac != null && b.frac < 0.2 ? "bad" : b.frac != null && b.frac < 0.35 ? "warn" : "";
    setV("#hud-bat", `${b.v != null ? b.v.toFixed(2) : "?"} V · ${b.a != null ? b.a.toFixed(1) + " A" : "? A"}${b.frac != null ? " · " + Math.round(b.frac * 100) + " %" : ""}${left}`, cls);
    $("#hud-bat").title = b.left_s != null ? `time left at the last 10 s mean current (${b.a_avg} A), from ${b.left_basis === "capacity" ? "the configured capacity" : "the observed discharge"}` : "time left: needs the current and a measurable discharge";
  } else setV("#hud-bat", "-");
  setV("#hud-link", `${state.pilot ? "you are the pilot" : l.pilot ? "pilot connected" : "no pilot"} · ${l.clients} page(s)` + (state.rttMs != null ? ` · rtt ${state.rttMs.toFixed(0)} ms` : ""));
  const cur = p && p.cur;
  $("#hud-current-cell").hidden = !cur;
  if (cur) setV("#hud-current", `${Math.hypot(cur[0], cur[1]).toFixed(2)} m/s towards ${wrap360(Math.atan2(cur[1], cur[0]) * DEG).toFixed(0)}°`);
  const bar = $("#hud-progress-bar span");
  if (pr && pr.length) {
    const frac = Math.max(0, Math.min(1, (pr.done || 0) / pr.length));
    bar.style.width = `${(frac * 100).toFixed(1)}%`;
    const next = pr.next >= 0 ? ` · node ${pr.next} in ${pr.to_next != null ? pr.to_next.toFixed(1) : "?"} m` : "";
    $("#hud-progress").textContent = `${Math.round(frac * 100)} % · ${pr.left != null ? pr.left.toFixed(1) : "?"} m left · ETA ${fmtDuration(pr.eta)}${next}`;
  } else { bar.style.width = "0"; $("#hud-progress").textContent = "no mission running"; }
  $("#hud-ctrl-cell").hidden = !c;
  if (c) setV("#hud-ctrl", `${c.controller} ${c.status} · solve ${c.solve_ms != null ? c.solve_ms.toFixed(1) : "?"} ms · xte ${c.xte != null ? c.xte.toFixed(2) : "?"} m`, c.status === "ok" ? "" : "warn");
  const ll = p && state.origin ? ` · ${fmtLatLon(...neToLatLon(p.n, p.e, state.origin))}` : "";
  setV("#hud-pose", p ? `N ${p.n.toFixed(2)} E ${p.e.toFixed(2)} (${p.src || "?"})${ll}` : "-");
  // supervisor warnings not already shown as alerts
  const shown = new Set([...alerts.items.keys()].map(k => k.replace(/^failsafe:/, "")));
  const warn = [...(s ? s.warnings : [])].filter(w => !shown.has(w.split(":")[0]) && !(w.startsWith("link_lost") && !l.ever));
  if (f.rc && (f.rc.active || f.rc.link !== "ok")) warn.push(`RC: ${f.rc.active ? "takeover ON" : "takeover off"} · link ${f.rc.link || "ok"}`);
  const html = warn.map(w => `<li>${esc(w)}</li>`).join("");
  const ul = $("#warnings");
  if (ul.innerHTML !== html) ul.innerHTML = html;
}

// -- what the operator can do now -----------------------------------------------------------
function actionState(action) {
  if (!state.connected) return { ok: false, why: "not connected to the boat" };
  if (!state.pilot) return action === "estop" && viewerMayStop() ? { ok: true, why: "" }
    : { ok: false, why: action === "estop" ? ESTOP_PILOT_ONLY : "take the controls first (pilot token)" };
  if (action === "estop") return { ok: true, why: "" };
  const s = state.telemetry && state.telemetry.sup;
  if (!s || (!s.available.length && !Object.keys(s.blocked).length)) return { ok: true, why: "" };   // an older core: no list
  if (s.available.includes(action)) return { ok: true, why: "" };
  return { ok: false, why: s.blocked[action] || "not possible now" };
}
state.actionState = actionState;
const ESTOP_PILOT_ONLY = "only the pilot can stop the boat — take controls";
// extra.web.viewer_may_estop: any page that reaches the boat may stop it (a second person on the jetty)
function viewerMayStop() { return !!(state.hello && state.hello.viewer_may_estop); }

function renderEstop() {   // always clickable (a viewer's tap explains and offers the token field)
  const b = $("#estop"), a = actionState("estop");
  const why = a.ok ? "" : a.why;
  b.classList.toggle("off", !a.ok);
  b.setAttribute("aria-disabled", String(!a.ok));
  if ($("#estop-why").textContent !== why) $("#estop-why").textContent = why;
}

function updateButtons() {
  $$("[data-action]").forEach(b => {
    const a = actionState(b.dataset.action);
    const enabled = b.id === "estop" ? true : a.ok;   // the e-stop button is always clickable (it explains)
    if (b.disabled === enabled) b.disabled = !enabled;
    const tip = a.ok ? (b.dataset.tip || b.title || "") : `${b.dataset.action}: ${a.why}`;
    if (!b.dataset.tip) b.dataset.tip = b.title || "";
    if (b.title !== tip) b.title = tip;
  });
  const use = $("#btn-use");
  const useWhy = !state.connected ? "not connected" : !state.pilot ? "take the controls first (pilot token)"
    : !route.complete() ? "the route needs a harbour and at least one node" : state.lastPlan && state.lastPlan.ok === false ? "the planner refused this route (see the errors)" : "";
  use.disabled = !!useWhy; use.title = useWhy || "plan once on the boat and send that plan (pilot)";
  $("#btn-from-boat").disabled = !(state.boatRoute && state.boatRoute.route);
  $("#btn-undo").disabled = !route.canUndo(); $("#btn-redo").disabled = !route.canRedo();
  const tilesWhy = !state.pilot ? "take the controls first (pilot token)" : !state.origin ? "no geographic origin" : !(state.hello && state.hello.tiles.enabled) ? "no tile cache on this server" : "";
  $("#btn-tiles").disabled = !!tilesWhy; $("#btn-tiles").title = tilesWhy || "download the tiles of the area in view to the boat's cache";
  renderEstop(); renderDriveState();
}

function renderNext() {
  const el = $("#next"), btn = $("#next-btn");
  const s = state.telemetry && state.telemetry.sup, pr = state.telemetry && state.telemetry.prog;
  let text, cls = "", act = null, label = "";
  const boatHas = s && s.route_id;
  const editorDiffers = route.complete() && (!state.boatRoute || routeDiff(route.toDict(), state.boatRoute.route || {}, EDIT_TOL).length > 0);
  if (!state.connected) text = "connecting to the boat…";
  else if (s && s.mode === "ESTOP") { text = "Emergency stop latched: check the boat, then reset the e-stop"; cls = "bad"; act = "reset_estop"; label = "Reset e-stop"; }
  else if (!state.pilot) { text = "Watching. To operate: paste the pilot token and press Take controls"; }
  else if (s && MOVING.includes(s.mode)) {
    cls = "ok";
    text = pr && pr.length ? `${s.mode}: ${Math.round(100 * pr.done / pr.length)} % of ${pr.length.toFixed(0)} m, ETA ${fmtDuration(pr.eta)}` : `${s.mode}`;
    act = "hold"; label = "Pause / hold";
  } else if (!boatHas && !route.complete()) text = "Draw a route: Harbour, then Node (or load a file)";
  else if (editorDiffers && route.complete()) { text = "Upload the route in the editor to the boat"; act = "upload"; label = "Upload"; }
  else if (s && !s.armed) { const a = actionState("arm"); text = a.ok ? "Arm the boat (thrust allowed)" : `Arm: ${a.why}`; act = a.ok ? "arm" : null; label = "Arm"; }
  else if (s) { const a = actionState("auto"); text = a.ok ? "Start the route (AUTO)" : `AUTO: ${a.why}`; act = a.ok ? "auto" : null; label = "Start auto"; }
  else text = "waiting for the boat's status…";
  const top = alerts.sorted()[0];
  if (top && (top.severity === "critical" || top.severity === "error") && cls !== "bad") cls = "bad";
  $("#next-text").textContent = text;
  el.className = "next " + cls;
  btn.hidden = !act; btn.textContent = label; btn.dataset.act = act || "";
}
$("#next-btn").onclick = () => {
  const a = $("#next-btn").dataset.act;
  if (a === "upload") upload(); else if (a) command(a);
};

// -- roles ------------------------------------------------------------------------------------
function setConn() {
  const c = $("#conn");
  c.textContent = state.connected ? "connected" : "offline — reconnecting";
  c.className = "badge " + (state.connected ? "ok" : "bad");
  updateButtons(); renderNext();
}

function setRole() {
  $("#role").textContent = state.pilot ? "pilot" : "viewer";
  $("#role").className = "badge " + (state.pilot ? "ok" : "");
  $("#btn-auth").hidden = state.pilot; $("#token").hidden = state.pilot;
  $("#btn-release").hidden = !state.pilot;
  if (state.pilot) $("#btn-takeover").hidden = true;
  updateButtons(); renderNext();
  if (!state.pilot) setPlanStatus(route.complete() ? "draft planning needs the pilot seat (the boat's route is shown in green)" : "draw a route: place the harbour, then nodes", "");
}

function authenticate(takeover) {
  const token = $("#token").value.trim() || state.token;
  if (!token) { toast("enter the pilot token (printed by `lotsen run`)", true); return; }
  state.token = token;
  $("#token").value = "";
  const msg = { type: "auth", token };
  if (takeover) msg.takeover = true;
  if (send(msg) === null) toast("connecting… the token is sent as soon as the boat answers");
}
$("#btn-auth").onclick = () => authenticate(false);
$("#token").addEventListener("keydown", ev => { if (ev.key === "Enter") authenticate(false); });
$("#btn-takeover").onclick = () => authenticate(true);
$("#btn-release").onclick = () => { driver.stop(); send({ type: "release" }); state.token = null; };

// -- operator commands -------------------------------------------------------------------------
function command(action) {
  if (!state.pilot && !(action === "estop" && viewerMayStop())) {
    toast(action === "estop" ? ESTOP_PILOT_ONLY : `${action}: take the controls first (pilot token)`, true);
    if (!$("#token").hidden) $("#token").focus();
    return;
  }
  const a = actionState(action);
  if (!a.ok) { alerts.push({ severity: "error", code: `web:blocked:${action}`, text: `${action} not possible: ${a.why}` }); return; }
  send({ type: "command", action });
}
$$("[data-action]").forEach(b => b.addEventListener("click", () => {
  if (b.dataset.action === "estop") driver.stop();
  command(b.dataset.action);
}));

// -- manual driving: keys, the on-screen pad, a gamepad ----------------------------------------
const driver = new KeyboardDriver({
  send: (c) => send({ type: "manual", surge: round3(c.surge), sway: round3(c.sway), yaw: round3(c.yaw) }),
  enabled: () => state.pilot && state.connected,
  gain: () => Number($("#gain").value),
  onChange: (keys, c, hint) => {
    $$("#drivepad [data-key]").forEach(s => s.classList.toggle("on", keys.has(s.dataset.key)));
    $("#manualcmd").textContent = `surge ${c.surge.toFixed(2)} · sway ${c.sway.toFixed(2)} · yaw ${c.yaw.toFixed(2)}`;
    if (hint) toast(hint, true);
  },
  onEstop: () => command("estop"),
});
state.driver = driver;
$("#gain").addEventListener("input", () => { $("#gainval").textContent = Number($("#gain").value).toFixed(2); });
function round3(x) { return Math.round(x * 1000) / 1000; }

// hold-to-drive pad: each finger holds one button (captured, so sliding off keeps it) until it
// lifts or the browser cancels the touch (scroll, palm, system gesture); focus loss stops all
$$("#drivepad [data-drive]").forEach(b => {
  const who = (ev) => `pad${ev.pointerId}`;
  b.addEventListener("pointerdown", ev => {
    ev.preventDefault();
    if (b.dataset.drive === "stop") { driver.stop(); return; }
    if (!driver.press(who(ev), b.dataset.drive)) return;
    try { b.setPointerCapture(ev.pointerId); } catch (e) { /* a synthetic pointer: no capture */ }
  });
  for (const type of ["pointerup", "pointercancel", "lostpointercapture"]) b.addEventListener(type, ev => driver.release(who(ev)));
  b.addEventListener("contextmenu", ev => ev.preventDefault());   // a long press is driving, not a menu
});

function renderDriveState() {
  const s = state.telemetry && state.telemetry.sup;
  const why = !state.connected ? "not connected to the boat" : !state.pilot ? "take the controls (pilot token) to drive"
    : !s ? "waiting for the boat's status" : s.mode !== "MANUAL" ? `the boat is in ${s.mode}: press Manual to drive`
    : !s.armed ? "arm first (thrust allowed)" : "";
  const el = $("#drivestate");
  const text = why || "hold a button to drive; lift to stop";
  if (el.textContent !== text) el.textContent = text;
  $("#drivepad").classList.toggle("off", !!why);
}

// gamepad (standard mapping): left stick ahead/astern and sideways, right stick turn, only while
// a shoulder button (the dead-man) is held; polled with the page visible and focused
const GAMEPAD_DEAD = 0.15;
function deadband(x) { return Math.abs(x) < GAMEPAD_DEAD ? 0 : (x - Math.sign(x) * GAMEPAD_DEAD) / (1 - GAMEPAD_DEAD); }
function pollGamepad() {
  const pads = navigator.getGamepads ? Array.from(navigator.getGamepads()).filter(Boolean) : [];
  const gp = pads[0];
  const usable = gp && gp.connected && !document.hidden && document.hasFocus();
  const held = usable && [4, 5, 6, 7].some(i => gp.buttons[i] && gp.buttons[i].pressed);
  const ax = (i) => deadband(gp.axes[i] || 0);
  driver.setAnalog(held ? { surge: -ax(1), sway: ax(0), yaw: ax(2) } : null);
  const text = !gp ? "gamepad: none (press a button on one to connect it)"
    : `gamepad: ${gp.id.slice(0, 40)} · ${held ? "driving" : "hold a shoulder button to drive"}`;
  if ($("#gamepad").textContent !== text) $("#gamepad").textContent = text;
}
setInterval(pollGamepad, PERIOD_MS);
window.addEventListener("gamepaddisconnected", () => driver.setAnalog(null));
state.pollGamepad = pollGamepad;

// -- route editing and planning ------------------------------------------------------------------
function setTool(tool) {
  map.setTool(tool);
  $$("#maptools .tool").forEach(b => b.classList.toggle("active", b.dataset.tool === tool));
  $("#btn-finish").hidden = !(tool === "area" || tool === "obstacle");
}
$$("#maptools .tool").forEach(b => b.addEventListener("click", () => setTool(b.dataset.tool)));
$("#btn-finish").onclick = () => { if (!route.finishPolygon()) toast("a polygon needs at least 3 corners", true); setTool("select"); };
$("#btn-fit").onclick = () => { map.fit(); state.viewTouched = true; };
$("#follow").onchange = (ev) => { map.follow = ev.target.checked; };
$("#btn-undo").onclick = () => route.undo();
$("#btn-redo").onclick = () => route.redo();
window.addEventListener("keydown", ev => {
  const t = ev.target;
  if (t.tagName === "INPUT" || t.tagName === "SELECT" || t.tagName === "TEXTAREA") return;
  if ((ev.ctrlKey || ev.metaKey) && ev.key.toLowerCase() === "z") { ev.preventDefault(); if (ev.shiftKey) route.redo(); else route.undo(); return; }
  if ((ev.ctrlKey || ev.metaKey) && ev.key.toLowerCase() === "y") { ev.preventDefault(); route.redo(); return; }
  if (ev.key === "Enter" && route.drawing) { route.finishPolygon(); setTool("select"); }
  if (ev.key === "Delete" || ev.key === "Backspace") {
    const sel = route.selected;
    if (sel && sel.kind === "node") route.deleteNode(sel.index);
    else if (sel && sel.kind === "vertex" && !route.deleteVertex(sel.poly, sel.k)) toast("a polygon keeps at least 3 corners (delete the polygon in the list)", true);
  }
});

route.onChange((replan) => {
  renderTable();
  map.invalidate();
  updateButtons(); renderReadback(); renderNext();
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
    $("#rampinfo").textContent = "";
    map.invalidate(); renderTable(); return;
  }
  if (!state.pilot) {   // planning runs on the boat's planner worker: the pilot's
    state.lastPlan = null; map.draftPath = null;
    setPlanStatus("draft planning needs the pilot seat (take the controls); the boat's route is shown in green", "");
    map.invalidate(); return;
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
    const r = res.start_ramp;
    $("#rampinfo").textContent = r && r.speed_mps > 0 ? `leaves the harbour from rest: 0 → ${r.speed_mps} m/s in ${r.distance_m} m (${r.time_s} s at ${r.accel_mps2} m/s²), then the node speeds` : "";
  } else {
    route.errors = res.errors || [{ kind: "route", message: res.error || "planning failed" }];
    map.draftPath = null;
    setPlanStatus(route.errors.map(e => e.message).join("\n"), "bad");
  }
  map.invalidate(); renderTable(); updateButtons();
}

function setPlanStatus(text, cls) {
  const el = $("#planstatus");
  el.textContent = text; el.className = "planstatus " + cls;
}

function renderTable() {
  const tb = $("#nodetable tbody");
  const rows = [];
  const sel = route.selected;
  const cell = (f, v) => `<td><input data-f="${f}" type="text" inputmode="decimal" value="${v}" aria-label="${f}"></td>`;
  const row = (label, p, kind, i) => {
    const err = route.errorFor(kind, i);
    const isSel = sel && sel.kind === kind && (kind === "harbour" || sel.index === i);
    const ll = state.origin ? fmtLatLon(...neToLatLon(p.north, p.east, state.origin)) : "";
    const speed = kind === "harbour" ? `<td class="dim" title="the harbour is a start from rest">0</td>` : cell("speed_mps", p.speed_mps);
    const actions = kind === "node"
      ? `<button type="button" data-ins="${i}" title="insert a node before this one">+</button><button type="button" data-del="${i}" title="delete node">✕</button>` : "";
    rows.push(`<tr data-kind="${kind}" data-i="${i ?? ""}" class="${isSel ? "selected" : ""} ${err ? "err" : ""}">` +
      `<td title="${ll}">${label}</td>${cell("north", p.north)}${cell("east", p.east)}${cell("heading_deg", p.heading_deg)}${speed}` +
      `<td>${actions}</td></tr>`);
    if (err) rows.push(`<tr class="err"><td></td><td colspan="5" class="errmsg">${esc(err.message)}</td></tr>`);
  };
  if (route.harbour) row("H", route.harbour, "harbour");
  route.nodes.forEach((n, i) => row(String(i), n, "node", i));
  const html = rows.join("");
  // keep the table while the user is typing in it (re-render would steal the focus)
  if (!tb.contains(document.activeElement) && tb.innerHTML !== html) tb.innerHTML = html;
  const polys = [];
  if (route.area) polys.push(`<div class="${route.errorFor("area") ? "err" : ""}">navigable area, ${route.area.length} corners <button type="button" data-delpoly="area" title="delete the area">✕</button></div>`);
  route.obstacles.forEach((o, i) => polys.push(`<div class="${route.errorFor("obstacle", i) ? "err" : ""}">obstacle ${i}, ${o.polygon.length} corners, forbidden ` +
    `<select data-forbid="${i}"><option ${o.forbidden === "inside" ? "selected" : ""}>inside</option><option ${o.forbidden === "outside" ? "selected" : ""}>outside</option></select>` +
    ` <button type="button" data-delpoly="${i}" title="delete the obstacle">✕</button></div>`));
  if (polys.length) polys.push(`<div class="hint">corners: drag; + on an edge inserts; select and Delete (or right-click) removes</div>`);
  $("#polylist").innerHTML = polys.join("");
  renderNodeGeo();
}

// the selected node, harbour or polygon corner, for editing in lat/lon: {label, n, e, set(n, e)}
function geoTarget() {
  const sel = route.selected;
  const p = route.point(sel);
  if (p) return { label: sel.kind === "harbour" ? "harbour" : `node ${sel.index}`, n: p.north, e: p.east, set: (n, e) => { p.north = n; p.east = e; } };
  const poly = sel && sel.kind === "vertex" ? route.polygon(sel.poly) : null;
  const c = poly ? poly[sel.k] : null;
  if (!c) return null;
  return { label: `${sel.poly === "area" ? "area" : "obstacle " + sel.poly} corner ${sel.k}`, n: c[0], e: c[1], set: (n, e) => { poly[sel.k] = [n, e]; } };
}

function renderNodeGeo() {
  const box = $("#nodegeo");
  const g = geoTarget();
  box.hidden = !(g && state.origin);
  if (box.hidden || box.contains(document.activeElement)) return;
  const [lat, lon] = neToLatLon(g.n, g.e, state.origin);
  $("#nodegeo-label").textContent = g.label;
  $("#geo-lat").value = lat.toFixed(7); $("#geo-lon").value = lon.toFixed(7);
  $("#geo-lat").classList.remove("invalid"); $("#geo-lon").classList.remove("invalid");
}

function fieldError(inp, text) {
  inp.classList.toggle("invalid", !!text);
  inp.title = text || "";
  $("#fielderr").textContent = text || "";
}

$("#nodetable").addEventListener("change", ev => {
  const inp = ev.target, tr = inp.closest("tr");
  if (!inp.dataset.f || !tr) return;
  const p = tr.dataset.kind === "harbour" ? route.harbour : route.nodes[Number(tr.dataset.i)];
  if (!p) return;
  const res = parseField(inp.dataset.f, inp.value);
  if (res.error) { fieldError(inp, `${tr.dataset.kind === "harbour" ? "harbour" : "node " + tr.dataset.i} ${res.error}`); inp.focus(); return; }
  fieldError(inp, "");
  p[inp.dataset.f] = res.value;
  inp.blur();
  route.changed();
});
$("#nodegeo").addEventListener("change", ev => {
  const inp = ev.target, g = geoTarget();
  if (!inp.dataset.geo || !g || !state.origin) return;
  const lat = parseField("lat", $("#geo-lat").value), lon = parseField("lon", $("#geo-lon").value);
  const bad = lat.error || lon.error;
  if (bad) { fieldError(inp, bad); return; }
  const [n, e] = latLonToNe(lat.value, lon.value, state.origin);
  const cn = parseField("north", String(n)), ce = parseField("east", String(e));
  if (cn.error || ce.error) { fieldError(inp, `too far from the origin: ${cn.error || ce.error}`); return; }
  fieldError(inp, "");
  g.set(Math.round(n * 1000) / 1000, Math.round(e * 1000) / 1000);
  inp.blur();
  route.changed();
});
$("#nodetable").addEventListener("click", ev => {
  const d = ev.target.dataset || {};
  if (d.del !== undefined) { route.deleteNode(Number(d.del)); return; }
  if (d.ins !== undefined) { if (!route.insertNode(Number(d.ins))) toast("cannot insert here", true); return; }
  const tr = ev.target.closest("tr[data-kind]");
  if (tr) { route.selected = tr.dataset.kind === "harbour" ? { kind: "harbour" } : { kind: "node", index: Number(tr.dataset.i) }; map.invalidate(); renderNodeGeo(); }
});
$("#polylist").addEventListener("click", ev => {
  const d = ev.target.dataset && ev.target.dataset.delpoly;
  if (d === undefined) return;
  route.deletePolygon(d === "area" ? "area" : Number(d));
});
$("#polylist").addEventListener("change", ev => {
  const i = ev.target.dataset && ev.target.dataset.forbid;
  if (i === undefined) return;
  route.obstacles[Number(i)].forbidden = ev.target.value;
  route.changed();
});

$("#btn-clear").onclick = () => { route.clear(); toast("route cleared (Undo brings it back)"); };
$("#btn-from-boat").onclick = () => { if (state.boatRoute) { route.fromDict(state.boatRoute.route); map.fit(); } };

// -- upload and read-back ------------------------------------------------------------------------
async function upload() {
  if (!route.complete()) { toast("the route needs a harbour and at least one node", true); return; }
  const sent = route.toDict();
  $("#readback").textContent = "uploading: planning on the boat…"; $("#readback").className = "readback";
  const res = await request({ type: "route", route: sent });
  if (res.type === "route_ok") {
    state.upload = { route_id: res.route_id, route: res.route };
    state.uploadedId = res.route_id;
    map.draftPath = res.path; map.invalidate();
    toast(`route uploaded (${res.length_m.toFixed(1)} m): waiting for the boat's read-back`);
    renderReadback();
  } else {
    alerts.push({ severity: "error", code: "web:upload", text: `upload refused: ${res.error || "unknown"}` });
    if (res.errors) { route.errors = res.errors; renderTable(); map.invalidate(); }
    renderReadback();
  }
}
$("#btn-use").onclick = upload;

function onReadback(m) {
  state.boatRoute = m;
  // first open: the editor shows what the boat holds (the demonstration route after `make run`)
  if (!route.complete() && !route.area && !route.obstacles.length && m.route) {
    route.fromDict(m.route);
    route.past = [route.snapshot()]; route.future = [];   // loading is not an undo step
  }
  renderReadback(); renderNext(); maybeFit(); updateButtons();
}

function renderReadback() {
  const el = $("#readback"), b = state.boatRoute, up = state.upload;
  let text = "the boat holds no route", cls = "";
  if (b && b.route) {
    const id = b.route_id || "?";
    if (up && up.route_id === b.route_id) {
      const diff = routeDiff(up.route, b.route);
      text = diff.length ? `read-back differs from the upload: ${diff.join("; ")}` : `✓ read-back matches the upload (route ${id})`;
      cls = diff.length ? "bad" : "ok";
    } else if (up && state.uploadedId === up.route_id) { text = `uploaded ${up.route_id}: waiting for the boat's read-back (it holds ${id})`; cls = "warn"; }
    else text = `the boat holds route ${id}`;
    if (route.complete() && routeDiff(route.toDict(), b.route, EDIT_TOL).length) {
      text += " · the editor differs (upload to apply)"; if (!cls) cls = "warn";
    }
  } else if (up) { text = `uploaded ${up.route_id}: waiting for the boat's read-back`; cls = "warn"; }
  el.textContent = `boat's route: ${text}`; el.className = "readback " + cls;
  state.readbackMatch = cls === "ok";
}

// -- files ------------------------------------------------------------------------------------------
async function save(format) {
  if (!route.complete()) { toast("nothing to save: place the harbour and nodes", true); return; }
  const res = await request({ type: "export", format, route: route.toDict() });
  if (res.type !== "export_result") { alerts.push({ severity: "error", code: "web:export", text: res.error }); return; }
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
  else alerts.push({ severity: "error", code: "web:import", text: res.error });
});

// -- offline map tiles -----------------------------------------------------------------------------
async function refreshTiles() {
  try {
    const r = await fetch("/api/tiles");
    const ix = await r.json();
    state.tilesIndex = ix;
    tiles.setIndex(ix);
    map.invalidate();
  } catch (e) { state.tilesIndex = null; }
  renderMaps();
}

function viewGeoBox() {
  if (!state.origin) return null;
  const [nMin, eMin, nMax, eMax] = map.viewBox();
  const c = [[nMin, eMin], [nMin, eMax], [nMax, eMin], [nMax, eMax]].map(([n, e]) => neToLatLon(n, e, state.origin));
  return { south: Math.min(...c.map(x => x[0])), north: Math.max(...c.map(x => x[0])), west: Math.min(...c.map(x => x[1])), east: Math.max(...c.map(x => x[1])) };
}

function renderMaps() {
  const ix = state.tilesIndex, h = state.hello;
  const zooms = ix && ix.zooms ? Object.keys(ix.zooms).map(Number).sort((a, b) => a - b) : [];
  $("#tilestatus").textContent = !h ? "offline map: -" : !h.tiles.enabled ? "offline map: no tile cache on this server (extra.web.tile_dir)"
    : !state.origin ? "offline map: no geographic origin, grid only"
    : `offline map: ${ix ? ix.count : 0} tiles cached${zooms.length ? ` (zoom ${zooms[0]}–${zooms[zooms.length - 1]})` : ": the map shows the metre grid"} · source ${h.tiles.source}`;
  const box = viewGeoBox();
  if (box) {
    $("#tilebox").textContent = `area in view: ${box.south.toFixed(5)}…${box.north.toFixed(5)}° N, ${box.west.toFixed(5)}…${box.east.toFixed(5)}° E`;
    const zmin = Number($("#tile-zmin").value), zmax = Number($("#tile-zmax").value);
    const n = Number.isInteger(zmin) && Number.isInteger(zmax) && zmin <= zmax ? tilesForBox(box.south, box.west, box.north, box.east, zmin, zmax) : NaN;
    const cap = h && h.tiles.max_count;
    $("#tilecount").textContent = isFinite(n) ? `${n} tiles${cap && n > cap ? ` — over the limit of ${cap}` : ""}` : "zoom range?";
  }
  updateButtons();
}
$("#tile-zmin").addEventListener("input", renderMaps);
$("#tile-zmax").addEventListener("input", renderMaps);
$("#show-tiles").addEventListener("change", ev => { tiles.visible = ev.target.checked; map.invalidate(); });

function suggestZooms() {   // the view's own zoom and a few coarser ones
  if (!state.origin) return;
  const ideal = Math.floor(Math.log2(156543.03392 * Math.cos(state.origin.lat * Math.PI / 180) * map.scale));
  const zmax = Math.max(1, Math.min((state.hello && state.hello.tiles.max_zoom) || 19, ideal + 1));
  $("#tile-zmax").value = zmax; $("#tile-zmin").value = Math.max(0, zmax - 3);
}

$("#btn-tiles").onclick = async () => {
  const box = viewGeoBox();
  if (!box) return;
  const msg = { type: "tiles_preload", ...box, zoom_min: Number($("#tile-zmin").value), zoom_max: Number($("#tile-zmax").value) };
  const res = await request(msg);
  if (res.type === "tiles_started") {
    $("#tileprog").hidden = false; $("#tileprog").max = res.total; $("#tileprog").value = 0;
    $("#tileprogtext").textContent = `pre-loading ${res.total} tiles…`; $("#btn-tiles-cancel").hidden = false;
  } else alerts.push({ severity: "error", code: "web:tiles", text: res.error });
};
$("#btn-tiles-cancel").onclick = () => send({ type: "tiles_cancel" });

function onTileProgress(m) {
  state.tileProgress = m;
  $("#tileprog").hidden = false; $("#tileprog").max = m.total || 1; $("#tileprog").value = m.done;
  $("#tileprogtext").textContent = `${m.state}: ${m.done} / ${m.total} tiles (${m.fetched} downloaded, ${m.cached} already cached, ${m.failed} failed)${m.error ? " — " + m.error : ""}`;
  if (m.state !== "running") {
    $("#btn-tiles-cancel").hidden = true;
    refreshTiles();
    if (m.state === "failed") alerts.push({ severity: "error", code: "web:tiles", text: `tile pre-load failed: ${m.error}` });
    else toast(`tile pre-load ${m.state}: ${m.fetched} downloaded`);
  } else if (m.done % 25 === 0) refreshTiles();
}

// -- logs -----------------------------------------------------------------------------------------------
async function refreshLogs() {
  try {
    const r = await fetch("/api/logs");
    const d = await r.json();
    state.logList = d.logs;
    $("#logsinfo").textContent = d.directory_set ? `${d.logs.length} file(s)` : "no log directory configured";
    $("#logtable tbody").innerHTML = d.logs.map(l =>
      `<tr><td>${esc(l.name)}${l.recording ? ' <span class="rec">● recording</span>' : ""}</td><td>${(l.size / 1e6).toFixed(1)} MB</td>` +
      `<td>${new Date(l.mtime * 1000).toLocaleString()}</td><td><a href="${esc(l.url)}" download="${esc(l.recording ? l.name.replace(/\.mcap$/, ".partial.mcap") : l.name)}" data-log="${esc(l.name)}">${l.recording ? "Download so far" : "Download"}</a>` +
      `<a href="${esc(l.foxglove)}" target="_blank" rel="noopener noreferrer" data-foxglove="${esc(l.name)}">Open in Foxglove</a></td></tr>`).join("");
  } catch (e) { $("#logsinfo").textContent = "could not list the logs"; }
}
$("#btn-logs").onclick = refreshLogs;
setInterval(() => { if (!$("#tab-logs").hidden) refreshLogs(); }, 3000);   // sizes and "(recording)" stay current

// the recording indicator: the active file's name, size and duration, polled from the boat
async function refreshRecording() {
  if (!state.hello || !state.hello.logs) { $("#hud-rec-cell").hidden = true; return; }
  let active = [];
  try { active = (await (await fetch("/api/recording")).json()).recording || []; } catch (e) { active = null; }
  state.recording = active;
  const cell = $("#hud-rec-cell");
  cell.hidden = !active || !active.length;
  if (cell.hidden) return;
  const r = active[0];
  $("#hud-rec").textContent = `● ${r.name} · ${(r.size / 1e6).toFixed(1)} MB · ${fmtDuration(r.duration_s)}` +
    (active.length > 1 ? ` (+${active.length - 1} more)` : "");
  const dl = $("#hud-rec-dl");
  if (dl.getAttribute("href") !== r.url) dl.setAttribute("href", r.url);
  dl.setAttribute("download", r.name.replace(/\.mcap$/, ".partial.mcap"));
}
setInterval(refreshRecording, 2000);
state.refreshRecording = refreshRecording;

// -- events, tabs, toasts --------------------------------------------------------------------------------
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
  if (m.ok) toast("magnetometer calibrated");
  else alerts.push({ severity: "error", code: "web:magcal", text: `magnetometer calibration failed: ${m.text}` });
}

$$("#tabs .tab").forEach(b => b.addEventListener("click", () => {
  $$("#tabs .tab").forEach(x => x.classList.toggle("active", x === b));
  $$(".tabpanel").forEach(p => { p.hidden = p.id !== `tab-${b.dataset.tab}`; });
  if (b.dataset.tab === "logs") refreshLogs();
  if (b.dataset.tab === "maps") { suggestZooms(); refreshTiles(); }
}));

$("#btn-sound").onclick = () => {
  const on = !alerts.sound;
  alerts.setSound(on);
  $("#btn-sound").textContent = on ? "sound on" : "sound off";
  $("#btn-sound").setAttribute("aria-pressed", String(on));
};

let toastTimer = null;
function toast(text, bad = false) {
  const t = $("#toast");
  t.textContent = text; t.className = "show" + (bad ? " bad" : "");
  clearTimeout(toastTimer);
  toastTimer = setTimeout(() => { t.className = ""; }, bad ? 4000 : 2500);
}

setRole(); setConn(); renderTable(); plan();
connect();
map.fitPoints([[0, 0]], 40);
