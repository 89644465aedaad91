// lotsen operator interface: connection to the boat, HUD and alerts, route editor with undo,
// upload with read-back, operation (arm, modes, keyboard), offline map tiles, logs.
import { RouteModel, parseField, routeDiff, longLegs, LIMITS, SURVEY_DEFAULTS, SURVEY_LIMITS } from "./route.js";
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
  telemetry: null, lastPlan: null, planSeq: 0, planTimer: null, planScheduled: 0, planPending: 0, nextId: 1, pending: new Map(),
  rttMs: null, framesRx: 0, mode: null, logs: [], origin: null,
  boatRoute: null,        // the boat's read-back {route, route_id}
  upload: null,           // this page's last upload {route_id, route}
  uploadedId: null,       // the last upload seen on the bus (any page)
  defaultSpeed: 0.5, uploadedDetours: [], uploadRefused: null, lastT: null, lastFrameMs: null, stale: true,
  viewTouched: false, fits: 0, tilesIndex: null, tileProgress: null, logList: [], lastRequest: null,
  requests: new Map(),    // request id -> {action, t0, lastSend, sends, answer}: every press until the boat answers
  paired: false,          // this device keeps the boat's pilot credential (scanned QR code or a token that worked)
};
window.lotsen = state;   // for debugging and the browser tests

// -- pairing: the boat's pilot credential kept on this device ---------------------------------
// A phone pairs by opening the address of the boat's QR code, http://boat:8080/#pair=<credential>:
// the fragment never reaches a server; it is taken off the address bar at once and kept in this
// browser's storage for this boat's address, and the page takes the controls with it at every
// (re)connect: after a restart of the boat's computer the phone is the pilot again by itself.
const PAIR_KEY = "lotsen.pilot-credential";
function storedCredential() { try { return localStorage.getItem(PAIR_KEY); } catch (e) { return null; } }
function storeCredential(token) {
  try { if (token) localStorage.setItem(PAIR_KEY, token); else localStorage.removeItem(PAIR_KEY); } catch (e) { /* private mode */ }
  state.paired = !!token;
  const f = document.querySelector("#btn-forget"); if (f) f.hidden = !token;
}
(function takePairingFromAddress() {
  const m = /(?:^#|&)pair=([^&]+)/.exec(location.hash);
  if (m) {
    storeCredential(decodeURIComponent(m[1]));
    history.replaceState(null, "", location.pathname + location.search);
  }
  state.token = storedCredential();
  state.paired = !!state.token;
})();

const route = new RouteModel();
const tiles = new TileLayer(() => map.invalidate());
const map = new MapView($("#map"), route, {
  defaultSpeed: () => state.defaultSpeed,   // the last valid entry of "new node speed"
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

const alerts = new AlertCenter($("#alerts"), {
  onChange: () => renderNext(),
  onCleared: (it, why) => onLog({ t: state.lastT, level: "info", source: "page", text: `cleared: ${it.text}${why ? " — " + why : ""}` }),
});
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
    case "auth_ok":
      state.pilot = true; alerts.clear("web:seat"); alerts.clear("web:bad_token"); alerts.clear("web:pairing");
      if (state.token) storeCredential(state.token);   // this device remembers the credential that worked
      setRole(); toast("you are the pilot"); schedulePlan(); break;
    case "pilot":
      state.pilot = !!m.pilot;
      if (m.revoked) { storeCredential(null); alerts.push({ severity: "error", code: "web:pairing", text: `controls lost: ${m.reason}` }); }
      if (!m.pilot && m.reason !== "released") { state.token = null; alerts.push({ severity: "error", code: "web:seat", text: `controls lost: ${m.reason}` }); }
      setRole(); if (m.reason === "released") toast("controls released"); break;
    case "path": map.activePath = m; map.activeDetours = detoursOnPath(); map.invalidate(); maybeFit(); break;
    case "model": state.model = m; renderSettings(); break;
    case "settings": onSettings(m); break;
    case "active_route": onReadback(m); break;
    case "uploaded": state.uploadedId = m.route_id; renderReadback(); break;
    case "alert": onAlert(m); break;
    case "log": onLog(m); break;
    case "magcal": onMagcal(m); break;
    case "ack": { const r = state.requests.get(m.request); if (r) r.server = true; state.lastRequest = { action: m.action, t: performance.now() }; renderRequests(); break; }
    case "confirmed": onConfirmed(m); break;
    case "tiles_progress": onTileProgress(m); break;
    case "coverage": onCoverage(m); break;
    case "evicted": alerts.push({ severity: "warning", code: "web:evicted", text: `disconnected by the boat's server: ${m.reason}; reconnecting` }); break;
    case "error": onError(m); break;
  }
}

function onHello(m) {
  alerts.clear("web:evicted");
  if (state.hello && m.server_t + 1 < state.lastT) resetLive();   // the boat's stack restarted: old trail and plots go
  state.hello = m;
  if (m.limits && m.limits.speed_max_mps) LIMITS.speed_mps[1] = m.limits.speed_max_mps;
  if (m.settings) onSettings(m.settings);
  state.uploadedDetours = m.uploaded_detours || [];
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
  if (m.code === "bad_token" && state.paired && state.token === storedCredential()) {
    storeCredential(null);   // the boat's credential was replaced (lotsen pair --new): this pairing is void
    alerts.push({ severity: "error", code: "web:pairing", text: "this device's pairing is no longer valid (the boat's credential was replaced): scan the boat's new QR code or type the credential" });
  }
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
  if (a.code === "refused:route") renderReadback(`the boat refused the upload: ${m.text}`);
  // the supervisor logs each of its alerts as a log event too: listed once in Events
  if (m.source !== "supervisor") onLog({ t: m.t, level: a.severity, source: m.source || "alert", text: `${a.active === false ? "cleared: " : ""}${m.text}` });
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
  if (state.lastT != null && f.t != null && f.t + 1 < state.lastT) resetLive();   // the clock went back: a restart
  state.lastT = f.t; state.lastFrameMs = performance.now();
  state.telemetry = f; state.framesRx++;
  if (state.stale) checkStale();   // live again with this frame, not up to 250 ms later
  const p = f.pose, c = f.ctrl, cmd = f.cmd || f.act;
  if (p) map.setBoat(p, f.truth);
  map.predicted = c && c.pred_n && c.pred_n.length ? { n: c.pred_n, e: c.pred_e } : null;
  plots.xte.push(f.t, [c ? c.xte : null]);
  const speed = p ? Math.hypot(p.u, p.v) : null;
  plots.speed.push(f.t, [speed, c ? c.speed_ref : null]);
  plots.heading.push(f.t, [p ? heading360(p.psi) : null, c && c.hdg_err != null ? c.hdg_err * DEG : null]);
  plots.props.push(f.t, [cmd ? cmd.n1 : null, cmd ? cmd.n2 : null, cmd ? cmd.nt : null, f.act && f.cmd ? (f.act.n1 + f.act.n2) / 2 : null]);
  plots.az.push(f.t, [cmd ? cmd.a1 * DEG : null, cmd ? cmd.a2 * DEG : null]);
  state.mode = f.sup ? f.sup.mode : null;
  renderHud(f);
  clearSettledAlerts(f);
  updateButtons();
  renderNext();
  maybeFit();
}
function wrap360(d) { return ((d % 360) + 360) % 360; }
// a heading as the operator reads it: whole degrees 0..359 (359.6 is 0, never 360 or negative)
function heading360(rad) { return Math.round(wrap360(rad * DEG)) % 360; }
state.heading360 = heading360;

// stale values: every live value greys when the link to the boat is lost or no frame came for
// STALE_MS (a half-open Wi-Fi link never closes the socket), and a value whose own stamp is older
// than its limit greys on its own (a sensor that stopped while the rest flows)
const STALE_MS = 2000;
const AGE_LIMIT_S = { sup: 1.5, ctrl: 1.5, gnss: 3.0, bat: 5.0, pose: 1.5, sea: 10.0 };
function checkStale() {
  const silent = state.lastFrameMs == null || performance.now() - state.lastFrameMs > STALE_MS;
  const stale = !state.connected || silent;
  if (document.body.classList.contains("stale") !== stale) {
    document.body.classList.toggle("stale", stale);
    map.stale = stale; map.invalidate();
    state.stale = stale;
    if (stale) driver.stop();   // no driving on old state
    updateButtons(); renderNext();   // what would start motion is not offered on old state
  }
  state.stale = stale;
  const c = $("#conn");
  const text = !state.connected ? "offline — reconnecting" : silent && state.lastFrameMs != null
    ? `no data for ${((performance.now() - state.lastFrameMs) / 1000).toFixed(0)} s` : "connected";
  if (c.textContent !== text) { c.textContent = text; c.className = "badge " + (text === "connected" ? "ok" : "bad"); }
}
setInterval(checkStale, 250);
function resetLive() {
  map.trail = []; map.activePath = null; map.activeDetours = [];
  Object.values(plots).forEach(p => p.clear && p.clear());
  map.invalidate();
}

// alerts whose cause has cleared: a refused request once the action is possible; the log keeps them
function clearSettledAlerts(f) {
  const s = f.sup;
  if (!s) return;
  for (const code of [...alerts.items.keys()]) {
    const m = /^(?:refused|web:blocked):(.+)$/.exec(code);
    if (m && (s.available.includes(m[1]) || (m[1] === "route" && s.route_id && state.upload && s.route_id === state.upload.route_id))) {
      alerts.clear(code, `${m[1]} is possible now`);
    }
  }
}
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
  setV("#hud-heading", p ? `${heading360(p.psi)}°` : "-");
  if (g) {
    const cls = g.fix === "RTK_FIXED" ? "ok" : g.fix === "RTK_FLOAT" ? "warn" : "bad";
    setV("#hud-gnss", `${g.fix} ±${g.h_acc != null ? g.h_acc.toFixed(3) : "?"} m · ${g.sv} satellites · correction age ${g.corr_age != null ? g.corr_age.toFixed(1) + " s" : "-"}`, cls);
  } else setV("#hud-gnss", "-");
  if (b) {
    const left = b.left_s != null ? ` · ${fmtDuration(b.left_s)} left` : "";
    const cls = b.frac != null && b.frac < 0.2 ? "bad" : b.frac != null && b.frac < 0.35 ? "warn" : "";
    setV("#hud-bat", `${b.v != null ? b.v.toFixed(2) : "?"} V · ${b.a != null ? b.a.toFixed(1) + " A" : "? A"}${b.frac != null ? " · " + Math.round(b.frac * 100) + " %" : ""}${left}`, cls);
    $("#hud-bat").title = b.left_s != null ? `time left at the last 10 s mean current (${b.a_avg} A), from ${b.left_basis === "capacity" ? "the configured capacity" : "the observed discharge"}` : "time left: needs the current and a measurable discharge";
  } else setV("#hud-bat", "-");
  setV("#hud-link", `${state.pilot ? "you are the pilot" : l.pilot ? "pilot connected" : "no pilot"} · ${l.clients} page(s)` + (state.rttMs != null ? ` · rtt ${state.rttMs.toFixed(0)} ms` : ""));
  const sea = f.sea;
  $("#hud-sea-cell").hidden = !sea;
  if (sea) setV("#hud-sea", sea.hs === 0 || sea.hs == null ? "flat water" :
    `Hs ${(sea.hs * 100).toFixed(0)} cm · Tp ${sea.tp != null ? sea.tp.toFixed(1) : "?"} s` +
    (sea.from != null ? ` · from ${Math.round(sea.from)}°` : "") +
    ` · roll ${sea.roll != null ? sea.roll.toFixed(1) : "?"}° pitch ${sea.pitch != null ? sea.pitch.toFixed(1) : "?"}° (std)`);
  const cur = p && p.cur;
  $("#hud-current-cell").hidden = !cur;
  if (cur) setV("#hud-current", `${Math.hypot(cur[0], cur[1]).toFixed(2)} m/s towards ${heading360(Math.atan2(cur[1], cur[0]))}°`);
  const bar = $("#hud-progress-bar span");
  // progress is published while the boat follows a path: shown then, and while paused (HOLD) on the
  // same route; otherwise the last figures would be stale
  const following = s && MOVING.includes(s.mode), paused = s && s.mode === "HOLD" && pr && pr.route_id === s.route_id && pr.left > 0.5;
  if (pr && pr.length && (following || paused)) {
    const frac = Math.max(0, Math.min(1, (pr.done || 0) / pr.length));
    bar.style.width = `${(frac * 100).toFixed(1)}%`;
    const next = pr.next >= 0 ? ` · node ${pr.next + 1} in ${pr.to_next != null ? pr.to_next.toFixed(1) : "?"} m` : "";
    $("#hud-progress").textContent = `${paused ? "paused at " : ""}${Math.round(frac * 100)} % · ${pr.left != null ? pr.left.toFixed(1) : "?"} m left` +
      (paused ? "" : ` · ETA ${fmtDuration(pr.eta)}`) + next;
  } else { bar.style.width = "0"; $("#hud-progress").textContent = "no mission running"; }
  $("#hud-ctrl-cell").hidden = !c;
  if (c) setV("#hud-ctrl", `${c.controller} ${c.status} · solve ${c.solve_ms != null ? c.solve_ms.toFixed(1) : "?"} ms · xte ${c.xte != null ? c.xte.toFixed(2) : "?"} m`, c.status === "ok" ? "" : "warn");
  const ll = p && state.origin ? ` · ${fmtLatLon(...neToLatLon(p.n, p.e, state.origin))}` : "";
  setV("#hud-pose", p ? `N ${p.n.toFixed(2)} E ${p.e.toFixed(2)} (${p.src || "?"})${ll}` : "-");
  // beside the drive pad: what the driver watches
  $("#dh-mode").textContent = s ? s.mode : "?";
  $("#dh-speed").textContent = sog == null ? "-" : `${sog.toFixed(2)} m/s`;
  $("#dh-heading").textContent = p ? `${heading360(p.psi)}°` : "-";
  $("#dh-armed").textContent = s ? (s.armed ? "ARMED" : "disarmed") : "";
  // supervisor warnings not already shown as alerts
  const shown = new Set([...alerts.items.keys()].map(k => k.replace(/^failsafe:/, "")));
  const warn = [...(s ? s.warnings : [])].filter(w => !shown.has(w.split(":")[0]) && !(w.startsWith("link_lost") && !l.ever));
  if (f.rc && (f.rc.active || f.rc.link !== "ok")) warn.push(`RC: ${f.rc.active ? "takeover ON" : "takeover off"} · link ${f.rc.link || "ok"}`);
  const html = warn.map(w => `<li>${esc(w)}</li>`).join("");
  const ul = $("#warnings");
  if (ul.innerHTML !== html) ul.innerHTML = html;
  // each value greys on its own when its stamp is older than its limit
  const old = (x, k) => !!(x && x.t != null && f.t != null && f.t - x.t > AGE_LIMIT_S[k]);
  const ages = { "#hud-mode": old(s, "sup"), "#hud-gnss": old(g, "gnss"), "#hud-bat": old(b, "bat"), "#hud-sea": old(sea, "sea"),
                 "#hud-speed": old(p, "pose"), "#hud-heading": old(p, "pose"), "#hud-pose": old(p, "pose"), "#hud-ctrl": old(c, "ctrl") };
  for (const [sel, isOld] of Object.entries(ages)) $(sel).classList.toggle("old", isOld);
}

// -- what the operator can do now -----------------------------------------------------------
function actionState(action) {
  if (!state.connected) return { ok: false, why: "not connected to the boat" };
  if (!state.pilot) return action === "estop" && viewerMayStop() ? { ok: true, why: "" }
    : { ok: false, why: action === "estop" ? ESTOP_PILOT_ONLY : "take the controls first (pilot token)" };
  if (action === "estop") return { ok: true, why: "" };
  // nothing that would start motion on old state: the boat may not be where the page shows it
  if (state.stale && MOTION_ACTIONS.includes(action)) return { ok: false, why: `no live data from the boat (${staleText()}): the state shown is old` };
  const s = state.telemetry && state.telemetry.sup;
  if (!s || (!s.available.length && !Object.keys(s.blocked).length)) return { ok: true, why: "" };   // an older core: no list
  if (s.available.includes(action)) return { ok: true, why: "" };
  return { ok: false, why: s.blocked[action] || "not possible now" };
}
state.actionState = actionState;
const ESTOP_PILOT_ONLY = "only the pilot can stop the boat — take controls";
const MOTION_ACTIONS = ["auto", "return", "arm", "manual", "calibrate_mag", "experiment", "reset_estop"];
function staleText() {
  return !state.connected ? "offline" : state.lastFrameMs == null ? "no data yet" : `no data for ${((performance.now() - state.lastFrameMs) / 1000).toFixed(0)} s`;
}
// extra.web.viewer_may_estop: any page that reaches the boat may stop it (a second person on the jetty)
function viewerMayStop() { return !!(state.hello && state.hello.viewer_may_estop); }

function renderEstop() {   // always clickable (a viewer's tap explains and offers the token field)
  const b = $("#estop"), a = actionState("estop");
  const pending = unconfirmed("estop");
  const why = pending ? `NOT CONFIRMED by the boat (${(pending / 1000).toFixed(1)} s) — sending again` : a.ok ? "" : a.why;
  b.classList.toggle("unconfirmed", !!pending);
  b.classList.toggle("off", !a.ok);
  b.setAttribute("aria-disabled", String(!a.ok));
  if ($("#estop-why").textContent !== why) $("#estop-why").textContent = why;
}

// each button's own tooltip, kept before any reason replaces it (a button without one had kept
// "not connected to the boat" once enabled)
$$("[data-action]").forEach(b => { if (!b.hasAttribute("data-tip")) b.setAttribute("data-tip", b.title || ""); });

function renderToggles() {   // RTK and logging: the state shown, one button each that switches it
  const f = state.telemetry || {}, g = f.gnss, rec = f.rec;
  const rtkOn = g ? /^RTK/.test(g.fix) : null;
  const logOn = rec ? !!rec.recording : (state.recording ? state.recording.length > 0 : null);
  for (const [sel, on, name, what] of [["#tog-rtk", rtkOn, "RTK", g ? g.fix : "no GNSS data"],
                                       ["#tog-log", logOn, "Logging", rec && rec.error ? "FAILED: " + rec.error : rec && rec.file ? rec.file : ""]]) {
    const b = $(sel);
    const action = on ? b.dataset.on : b.dataset.off;
    if (b.dataset.action !== action) b.dataset.action = action;
    b.setAttribute("aria-pressed", String(!!on));
    const text = `${name}: ${on == null ? "?" : on ? "ON" : "off"} — ${on ? "tap to stop" : "tap to start"}`;
    if (b.textContent !== text) b.textContent = text;
    b.dataset.tip = `${name} is ${on == null ? "unknown" : on ? "on" : "off"}${what ? " (" + what + ")" : ""}`;
  }
}

function updateButtons() {
  renderToggles();
  $$("[data-action]").forEach(b => {
    const a = actionState(b.dataset.action);
    const enabled = b.id === "estop" ? true : a.ok;   // the e-stop button is always clickable (it explains)
    if (b.disabled === enabled) b.disabled = !enabled;
    const tip = a.ok ? b.dataset.tip : `${b.dataset.action}: ${a.why}`;
    if (tip && b.title !== tip) b.title = tip; else if (!tip && b.hasAttribute("title")) b.removeAttribute("title");
  });
  const s = state.telemetry && state.telemetry.sup;
  $("#estop-reset").hidden = !(s && s.mode === "ESTOP" && state.pilot);   // the way out, beside the e-stop itself
  const drive = actionState("manual");
  $("#btn-drive").disabled = !state.pilot || (!drive.ok && !(s && s.mode === "MANUAL"));
  $("#btn-drive").title = !state.pilot ? "take the controls first (pilot token)" : drive.ok || (s && s.mode === "MANUAL") ? "Manual mode and the drive pad" : `manual: ${drive.why}`;
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
  if (a === "upload") confirmUpload(); else if (a) command(a);
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
  updateButtons(); renderNext(); renderSettings();
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
$("#btn-forget").onclick = () => { storeCredential(null); state.token = null; toast("this device forgot the boat's pilot credential"); };
$("#btn-forget").hidden = !state.paired;

// -- operator commands -------------------------------------------------------------------------
function command(action) {
  if (!state.pilot && !(action === "estop" && viewerMayStop())) {
    toast(action === "estop" ? ESTOP_PILOT_ONLY : `${action}: take the controls first (pilot token)`, true);
    if (!$("#token").hidden) $("#token").focus();
    return;
  }
  const a = actionState(action);
  if (!a.ok) { alerts.push({ severity: "error", code: `web:blocked:${action}`, text: `${action} not possible: ${a.why}` }); return; }
  request_(action);
}

// -- every request until the boat answers ---------------------------------------------------------
// Each press gets an id; the boat answers each id once (`confirmed`: accepted with the mode after it,
// or refused with the reason). Unanswered after CONFIRM_MS the page says so plainly and sends it
// again every RESEND_MS with the same id (the boat acts on it once): a frozen web server or a Wi-Fi
// that drops packets keeps the socket open and would otherwise swallow the e-stop unseen. The
// e-stop and disarm are sent until the boat answers; a mode change for MODE_RESEND_MS.
const CONFIRM_MS = 1000, RESEND_MS = 500, MODE_RESEND_MS = 10000, KEEP_SENDING = ["estop", "disarm"];
function newRequestId() {
  const b = new Uint8Array(8); crypto.getRandomValues(b);
  return "p" + Array.from(b, x => x.toString(16).padStart(2, "0")).join("");
}
function request_(action) {
  const now = performance.now(), rid = newRequestId();
  for (const r of state.requests.values()) if (!r.answer && r.action !== "estop") r.superseded = true;   // the newest press counts
  state.requests.set(rid, { rid, action, t0: now, lastSend: now, sends: 1, answer: null });
  send({ type: "command", action, request: rid });
  renderRequests();
}
function onConfirmed(m) {
  const r = state.requests.get(m.request);
  if (!r || r.answer) return;
  r.answer = m; r.tAnswer = performance.now();
  renderRequests(); updateButtons();
}
function unconfirmed(action) {   // ms an unanswered request of `action` has waited past CONFIRM_MS (0: none)
  const now = performance.now();
  let worst = 0;
  for (const r of state.requests.values()) if (r.action === action && !r.answer && !r.superseded && now - r.t0 >= CONFIRM_MS) worst = Math.max(worst, now - r.t0);
  return worst;
}
state.unconfirmed = unconfirmed;
function requestTick() {
  const now = performance.now();
  for (const [rid, r] of state.requests) {
    if (r.answer || r.superseded) { if (now - (r.tAnswer || r.t0) > 8000) state.requests.delete(rid); continue; }
    const keep = KEEP_SENDING.includes(r.action) || now - r.t0 < MODE_RESEND_MS;
    if (keep && now - r.lastSend >= RESEND_MS && send({ type: "command", action: r.action, request: rid }) !== null) { r.lastSend = now; r.sends++; }
    if (!keep) r.gaveUp = true;
  }
  renderRequests(); renderEstop();
}
setInterval(requestTick, 250);
function renderRequests() {
  const now = performance.now(), el = $("#cmdstate");
  const list = [...state.requests.values()].filter(r => !r.superseded);
  // what the operator must see first: an unanswered e-stop, then the newest request
  const r = list.find(x => x.action === "estop" && !x.answer) || list[list.length - 1];
  let text = "", cls = "";
  if (r && !r.answer && r.gaveUp) { text = `${r.action}: NOT CONFIRMED by the boat after ${((now - r.t0) / 1000).toFixed(0)} s — check the boat`; cls = "bad"; }
  else if (r && !r.answer && now - r.t0 >= CONFIRM_MS) { text = `${r.action}: NOT CONFIRMED by the boat (${((now - r.t0) / 1000).toFixed(1)} s) — sending again`; cls = "unconfirmed"; }
  else if (r && !r.answer) { text = `${r.action}: sent, waiting for the boat…`; cls = "wait"; }
  else if (r && r.answer.accepted) { text = `✓ the boat confirmed ${r.action} (${r.answer.mode}${r.answer.armed ? ", armed" : ""})`; cls = "ok"; }
  else if (r) { text = `✗ the boat refused ${r.action}: ${r.answer.reason}`; cls = "bad"; }
  if (el.textContent !== text) el.textContent = text;
  el.className = "cmdstate " + cls;
}
$$("[data-action]").forEach(b => b.addEventListener("click", () => {
  if (b.dataset.action === "estop") driver.stop();
  command(b.dataset.action);
}));

// -- manual driving: keys, the on-screen pad, a gamepad ----------------------------------------
const driver = new KeyboardDriver({
  send: (c) => send({ type: "manual", surge: round3(c.surge), sway: round3(c.sway), yaw: round3(c.yaw) }),
  enabled: () => state.pilot && state.connected && !state.stale,
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
  const manual = actionState("manual");
  const why = !state.connected ? "not connected to the boat" : !state.pilot ? "take the controls (pilot token) to drive"
    : state.stale ? `no live data from the boat (${staleText()}): not driving on old state`
    : !s ? "waiting for the boat's status"
    : s.mode === "ESTOP" ? "emergency stop latched: Reset e-stop (beside the e-stop), then Drive (Manual) and Arm"
    : s.mode !== "MANUAL" ? (manual.ok ? `the boat is in ${s.mode}: tap Drive (Manual)` : `the boat is in ${s.mode}; Manual: ${manual.why}`)
    : !s.armed ? "arm first (thrust allowed)" : "";
  const el = $("#drivestate");
  const text = why || "hold a button to drive; lift to stop";
  if (el.textContent !== text) el.textContent = text;
  $("#drivepad").classList.toggle("off", !!why);
}

// one tap from the first screen: Manual, the Operate tab, the pad in view with mode, speed and heading beside it
$("#btn-drive").onclick = () => {
  const s = state.telemetry && state.telemetry.sup;
  if (!s || s.mode !== "MANUAL") command("manual");
  showTab("operate");
  $("#drivebox").scrollIntoView({ block: "start", behavior: "instant" });
};

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
  $("#btn-finish").hidden = !(tool === "area" || tool === "obstacle" || tool === "survey");
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
  state.planPending = ++state.planScheduled;   // a draft plan is due: the page's text will still change
  state.planTimer = setTimeout(plan, 150);
}

async function plan() {
  const mine = state.planScheduled;
  try { await planDraft(); } finally { if (state.planPending === mine) state.planPending = 0; }
}

async function planDraft() {
  renderSurvey();
  if (!route.complete()) {
    route.errors = []; map.draftPath = null; state.lastPlan = null; map.surveyLines = null; map.surveyPolygon = null;
    setPlanStatus(route.harbour ? (route.survey ? "draw the survey polygon (Survey tool), or survey the whole area" : "add at least one route node")
      : "place the harbour node (Harbour tool), then route nodes or a survey", "");
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
    const det = res.detours || [];
    map.draftDetours = det;
    const vmax = Math.max(...res.path.v);
    const long = longLegs(route);
    const sv = res.survey;
    map.surveyLines = sv ? sv.lines : null; map.surveyPolygon = sv ? sv.polygon : null;
    $("#surveyinfo").textContent = sv ? `survey: ${sv.count} lines, ${sv.line_length_m.toFixed(0)} m of lines at ${sv.speed_mps} m/s ` +
      `(${fmtDuration(sv.line_time_s)}, ${Math.round(100 * sv.share_on_lines)} % of the planned time); the whole route ` +
      `${res.length_m.toFixed(0)} m, about ${fmtDuration(res.duration_s)}; turns of ${sv.turn_radius_m} m radius` : "";
    setPlanStatus(`planned: ${res.length_m.toFixed(1)} m, about ${fmtDuration(res.duration_s)}, up to ${vmax.toFixed(2)} m/s` +
      det.map(d => `\ndetour: ${d.leg} goes round an obstacle or the area edge (${d.length_m.toFixed(1)} m of path, ${d.straight_m.toFixed(1)} m in a straight line)`).join("") +
      long.map(l => `\ncheck: ${longLegText(l)}`).join(""), long.length ? "warn" : "ok");
    const r = res.start_ramp;
    $("#rampinfo").textContent = r && r.speed_mps > 0 ? `leaves the harbour from rest: 0 → ${r.speed_mps} m/s in ${r.distance_m} m (${r.time_s} s at ${r.accel_mps2} m/s²), then the node speeds` : "";
  } else {
    route.errors = res.errors || [{ kind: "route", message: res.error || "planning failed" }];
    map.draftPath = null; map.draftDetours = []; map.surveyLines = null; map.surveyPolygon = null;
    setPlanStatus(route.errors.map(e => e.message).join("\n") + longLegs(route).map(l => `\ncheck: ${longLegText(l)}`).join(""), "bad");
  }
  map.invalidate(); renderTable(); updateButtons();
}

// -- the survey tool: settings of the drawn (or whole-area) survey; the boat's planner makes the lines
const SURVEY_FIELDS = ["spacing_m", "angle_deg", "speed_mps", "turnaround_m"];
function renderSurvey() {
  const s = route.survey;
  for (const k of SURVEY_FIELDS) {
    const inp = $(`#sv-${k}`);
    if (document.activeElement !== inp) inp.value = s && s[k] !== undefined ? String(s[k]) : String(SURVEY_DEFAULTS[k]);
    inp.removeAttribute("aria-invalid");
  }
  $("#sv-crosshatch").checked = !!(s && s.crosshatch);
  $("#btn-survey-off").disabled = !s;
  if (!s) $("#surveyinfo").textContent = "draw the survey polygon with the Survey tool, or survey the whole area";
}
function surveyField(k, text) {
  const [lo, hi, unit] = SURVEY_LIMITS[k];
  const t = String(text).trim().replace(",", ".");
  const v = Number(t);
  if (t === "" || !Number.isFinite(v)) return { error: `${k.replace(/_.*/, "")}: "${t.slice(0, 20)}" is not a number` };
  if (v < lo || v > hi) return { error: `${k.replace(/_.*/, "")}: ${t.slice(0, 20)} ${unit} is outside ${lo} to ${hi} ${unit}` };
  return { value: v };
}
for (const k of SURVEY_FIELDS) {
  $(`#sv-${k}`).addEventListener("change", (ev) => {
    const res = surveyField(k, ev.target.value);
    if (res.error) { ev.target.setAttribute("aria-invalid", "true"); $("#surveyinfo").textContent = `${res.error} (not applied)`; return; }
    if (!route.survey) { toast("draw the survey polygon first (Survey tool), or Survey the area", true); renderSurvey(); return; }
    route.survey[k] = res.value; route.changed();
  });
}
$("#sv-crosshatch").addEventListener("change", (ev) => { if (route.survey) { route.survey.crosshatch = ev.target.checked; route.changed(); } });
$("#btn-survey-area").onclick = () => {
  if (!route.area) { toast("draw the navigable area first (Area tool)", true); return; }
  const vals = {};
  for (const k of SURVEY_FIELDS) { const r = surveyField(k, $(`#sv-${k}`).value); vals[k] = r.error ? SURVEY_DEFAULTS[k] : r.value; }
  route.survey = { ...SURVEY_DEFAULTS, ...vals, crosshatch: $("#sv-crosshatch").checked, polygon: null };
  route.nodes = []; route.changed();
};
$("#btn-survey-off").onclick = () => { route.survey = null; map.surveyLines = null; map.surveyPolygon = null; route.changed(); };
// the drafted route's time and energy, predicted by the boat's planner on the model in use in the current
// the estimator knows (lotsen.stack.page_prediction); the mission report compares it with what was flown
$("#btn-predict").onclick = async () => {
  if (!state.pilot) { toast("take the controls first (pilot token)", true); return; }
  $("#btn-predict").disabled = true;
  $("#predictinfo").textContent = "predicting: the route flown on the model in use (simulated time)…";
  const res = await request({ type: "predict", route: route.toDict() });
  $("#btn-predict").disabled = false;
  if (res.type === "predict_result" && res.ok) {
    const c = Math.hypot(res.current_ne_mps[0], res.current_ne_mps[1]);
    $("#predictinfo").textContent = `predicted: ${fmtDuration(res.duration_s)}` +
      (res.share_on_lines != null ? ` (${Math.round(100 * res.share_on_lines)} % on lines)` : "") +
      `, ${res.energy_Wh.toFixed(1)} Wh` +
      (res.draws > 1 && res.energy_range_Wh ? ` (${res.energy_range_Wh[0].toFixed(1)}-${res.energy_range_Wh[1].toFixed(1)} over ${res.draws} flights)` : "") +
      ` at the motors (mean ${res.mean_power_W.toFixed(0)} W); ${res.controller} on the ${res.model},` +
      ` in the estimated current ${c.toFixed(2)} m/s` + (res.reached_end ? "" : "; the model did NOT reach the end");
  } else $("#predictinfo").textContent = `no prediction: ${res.error || (res.errors && res.errors[0].message) || "failed"}`;
};
$("#btn-rerun").onclick = async () => {
  const res = await request({ type: "rerun" });
  if (res.type === "rerun_result") { route.fromDict(res.route); map.fit(); toast(`re-run over the holes loaded: ${res.route.survey.lines.length} lines (check, then Upload)`); }
  else toast(res.error || "no re-run route", true);
};

// the live coverage layer: cells with soundings by depth, the survey's holes
function onCoverage(m) {
  if (!map.coverage || m.reset || map.coverage.cell_m !== m.cell_m) map.coverage = { cell_m: m.cell_m, cells: new Map(), holes: [], lo: Infinity, hi: -Infinity };
  const c = map.coverage;
  for (const [i, j, depth, count] of m.cells) {
    c.cells.set(`${i},${j}`, [depth, count]);
    c.lo = Math.min(c.lo, depth); c.hi = Math.max(c.hi, depth);
  }
  if (m.survey) c.holes = m.survey.holes || [];
  $("#coverageinfo").textContent = m.survey
    ? `coverage: ${(100 * m.survey.fraction).toFixed(1)} % of ${m.survey.cells} cells of ${m.cell_m} m, ${m.survey.hole_cells} cells in ${m.survey.holes.length} holes; ${m.soundings} soundings, ${c.lo.toFixed(2)}–${c.hi.toFixed(2)} m deep`
    : `depth map: ${m.soundings} soundings in cells of ${m.cell_m} m, ${c.lo.toFixed(2)}–${c.hi.toFixed(2)} m deep`;
  $("#btn-rerun").disabled = !(m.survey && m.survey.hole_cells > 0);
  map.invalidate();
}

function setPlanStatus(text, cls) {
  const el = $("#planstatus");
  el.textContent = text; el.className = "planstatus " + cls;
}

function renderTable() {
  const tb = $("#nodetable tbody");
  const rows = [];
  const sel = route.selected;
  const names = { north: "north (m)", east: "east (m)", heading_deg: "bearing (°)", speed_mps: "speed (m/s)" };
  const row = (label, p, kind, i) => {
    const err = route.errorFor(kind, i);
    // the planner's error names its field: that cell is marked
    const cell = (f, v) => {
      const bad = err && err.field === f;
      return `<td><input data-f="${f}" type="text" inputmode="decimal" value="${v}" aria-label="${label === "H" ? "harbour" : "node " + label} ${names[f]}"` +
        `${bad ? ` class="invalid" aria-invalid="true" title="${esc(err.message)}"` : ""}></td>`;
    };
    const isSel = sel && sel.kind === kind && (kind === "harbour" || sel.index === i);
    const ll = state.origin ? fmtLatLon(...neToLatLon(p.north, p.east, state.origin)) : "";
    const speed = kind === "harbour" ? `<td class="dim" title="the harbour is a start from rest">0</td>` : cell("speed_mps", p.speed_mps);
    const actions = kind === "node"
      ? `<button type="button" data-ins="${i}" title="insert a node before this one">+</button><button type="button" data-del="${i}" title="delete node">✕</button>` : "";
    rows.push(`<tr data-kind="${kind}" data-i="${i ?? ""}" class="${isSel ? "selected" : ""} ${err ? "err" : ""}">` +
      `<td title="${ll}">${label}</td>${cell("north", p.north)}${cell("east", p.east)}${cell("heading_deg", Math.round(wrap360(p.heading_deg) * 1000) / 1000 % 360)}${speed}` +
      `<td>${actions}</td></tr>`);
    if (err) rows.push(`<tr class="err"><td></td><td colspan="5" class="errmsg">${esc(err.message)}</td></tr>`);
  };
  if (route.harbour) row("H", route.harbour, "harbour");
  route.nodes.forEach((n, i) => row(String(i + 1), n, "node", i));   // counted from 1, as in every message
  const html = rows.join("");
  // keep the table while the user is typing in it (re-render would steal the focus)
  if (!tb.contains(document.activeElement) && tb.innerHTML !== html) tb.innerHTML = html;
  const polys = [];
  if (route.area) polys.push(`<div class="${route.errorFor("area") ? "err" : ""}">navigable area, ${route.area.length} corners <button type="button" data-delpoly="area" title="delete the area">✕</button></div>`);
  if (route.survey && route.survey.polygon) polys.push(`<div>survey polygon, ${route.survey.polygon.length} corners <button type="button" data-delpoly="survey" title="delete the survey">✕</button></div>`);
  route.obstacles.forEach((o, i) => polys.push(`<div class="${route.errorFor("obstacle", i) ? "err" : ""}">obstacle ${i + 1}, ${o.polygon.length} corners, forbidden ` +
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
  if (p) return { label: sel.kind === "harbour" ? "harbour" : `node ${sel.index + 1}`, n: p.north, e: p.east, set: (n, e) => { p.north = n; p.east = e; } };
  const poly = sel && sel.kind === "vertex" ? route.polygon(sel.poly) : null;
  const c = poly ? poly[sel.k] : null;
  if (!c) return null;
  return { label: `${sel.poly === "area" || sel.poly === "survey" ? sel.poly : "obstacle " + (sel.poly + 1)} corner ${sel.k + 1}`, n: c[0], e: c[1], set: (n, e) => { poly[sel.k] = [n, e]; } };
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

// a refused entry: marked (aria-invalid, described by its message) and the message right beside
// the field, with a Restore button (a phone keyboard has no Esc); `restore`: the value in use
let errSeq = 0;
function fieldError(inp, text, restore) {
  inp.classList.toggle("invalid", !!text);
  inp.title = text || "";
  $("#fielderr").textContent = text || "";
  let box = inp.dataset.errId ? document.getElementById(inp.dataset.errId) : null;
  if (!text) {
    if (box) box.remove();
    inp.removeAttribute("aria-invalid"); inp.removeAttribute("aria-describedby"); delete inp.dataset.errId;
    return;
  }
  if (!box) {
    box = document.createElement("div");
    box.className = "fielderr-inline"; box.id = `fielderr-${++errSeq}`; box.setAttribute("role", "alert");
    (inp.closest("label") || inp).insertAdjacentElement("afterend", box);
    inp.dataset.errId = box.id;
  }
  const html = `<span>${esc(text)}</span>` + (restore !== undefined ? `<button type="button" class="restore">Restore ${esc(String(restore))}</button>` : "");
  if (box.innerHTML !== html) box.innerHTML = html;
  const btn = box.querySelector("button.restore");
  if (btn) {
    const back = () => { inp.value = String(restore); fieldError(inp, ""); };
    // on the finger's touch, before the field loses the focus (its change event would refuse again)
    btn.onpointerdown = (ev) => { ev.preventDefault(); back(); };
    btn.onclick = back;
  }
  inp.setAttribute("aria-invalid", "true"); inp.setAttribute("aria-describedby", box.id);
}
state.fieldError = fieldError;

// "new node speed" is checked like a table cell: a refused entry is marked and not used
$("#default-speed").addEventListener("change", ev => {
  const inp = ev.target, res = parseField("speed_mps", inp.value);
  if (res.error) { fieldError(inp, `new node ${res.error} (not applied: new nodes get ${state.defaultSpeed} m/s; Restore or Esc brings it back)`, state.defaultSpeed); return; }
  state.defaultSpeed = res.value; fieldError(inp, "");
});
// Esc in a field cancels the edit: the value in use comes back
document.addEventListener("keydown", ev => {
  const inp = ev.target;
  if (ev.key !== "Escape" || inp.tagName !== "INPUT") return;
  if (inp.id === "default-speed") { inp.value = state.defaultSpeed; state.driver.editStart.set(inp, inp.value); fieldError(inp, ""); }
  else if (inp.classList.contains("invalid")) fieldError(inp, "");
}, true);

$("#nodetable").addEventListener("change", ev => {
  const inp = ev.target, tr = inp.closest("tr");
  if (!inp.dataset.f || !tr) return;
  const p = tr.dataset.kind === "harbour" ? route.harbour : route.nodes[Number(tr.dataset.i)];
  if (!p) return;
  const res = parseField(inp.dataset.f, inp.value);
  if (res.error) {
    const keeps = tr.dataset.kind === "harbour" && inp.dataset.f === "speed_mps" ? "" : ` (not applied: the route keeps ${p[inp.dataset.f]}; Restore or Esc brings it back)`;
    fieldError(inp, `${tr.dataset.kind === "harbour" ? "harbour" : "node " + (Number(tr.dataset.i) + 1)} ${res.error}${keeps}`, p[inp.dataset.f]); inp.focus(); return;
  }
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
  route.deletePolygon(d === "area" || d === "survey" ? d : Number(d));
});
$("#polylist").addEventListener("change", ev => {
  const i = ev.target.dataset && ev.target.dataset.forbid;
  if (i === undefined) return;
  route.obstacles[Number(i)].forbidden = ev.target.value;
  route.changed();
});

// Clear asks first: the nodes only (the usual), or the navigable area too
$("#btn-clear").onclick = () => { $("#clearbox").hidden = false; $("#btn-clear-nodes").focus(); };
$("#btn-clear-nodes").onclick = () => { $("#clearbox").hidden = true; route.clearNodes(); toast("nodes cleared, the area kept (Undo brings them back)"); };
$("#btn-clear-all").onclick = () => { $("#clearbox").hidden = true; route.clear(); toast("route and area cleared (Undo brings them back)"); };
$("#btn-clear-cancel").onclick = () => { $("#clearbox").hidden = true; };
$("#btn-from-boat").onclick = () => { if (state.boatRoute) { route.fromDict(state.boatRoute.route); map.fit(); } };

// -- upload and read-back ------------------------------------------------------------------------
function longLegText(l) {
  return `${l.leg} is ${l.length_m.toFixed(0)} m, ${(l.length_m / Math.max(l.median_m, 0.1)).toFixed(0)}x the other legs (median ${l.median_m.toFixed(0)} m): a typo?`;
}
// a leg much longer than the rest is flagged before upload: the upload waits for "Upload anyway"
function confirmUpload() {
  if (!route.complete()) { toast("the route needs a harbour and at least one node", true); return; }
  const long = longLegs(route);
  if (!long.length) { upload(); return; }
  $("#uploadbox-text").textContent = long.map(longLegText).join("; ");
  $("#uploadbox").hidden = false;
}
$("#btn-upload-anyway").onclick = () => { $("#uploadbox").hidden = true; upload(); };
$("#btn-upload-cancel").onclick = () => { $("#uploadbox").hidden = true; };
state.longLegs = () => longLegs(route);

async function upload() {
  if (!route.complete()) { toast("the route needs a harbour and at least one node", true); return; }
  const sent = route.toDict();
  $("#readback").textContent = "uploading: planning on the boat…"; $("#readback").className = "readback";
  const res = await request({ type: "route", route: sent });
  state.uploadRefused = null;
  if (res.type === "route_ok") {
    state.upload = { route_id: res.route_id, route: res.route };
    state.uploadedId = res.route_id;
    state.uploadedDetours = res.detours || [];
    alerts.clear("web:upload", "a later upload was accepted");
    map.draftPath = res.path; map.invalidate();
    toast(`route uploaded (${res.length_m.toFixed(1)} m): waiting for the boat's read-back`);
    renderReadback();
  } else {
    alerts.push({ severity: "error", code: "web:upload", text: `upload refused: ${res.error || "unknown"}` });
    if (res.errors) { route.errors = res.errors; renderTable(); map.invalidate(); }
    renderReadback(`upload refused: ${res.error || "unknown"}`);
  }
}
$("#btn-use").onclick = confirmUpload;

function onReadback(m) {
  if (state.upload && m.route_id === state.upload.route_id) state.uploadRefused = null;
  state.boatRoute = m;
  map.activeDetours = detoursOnPath();
  // first open: the editor shows what the boat holds (the demonstration route after `make run`)
  if (!route.complete() && !route.area && !route.obstacles.length && m.route) {
    route.fromDict(m.route);
    route.past = [route.snapshot()]; route.future = [];   // loading is not an undo step
  }
  renderReadback(); renderNext(); maybeFit(); updateButtons();
}

// refused: why the last upload was refused (by this page's planner or by the boat). The boat then
// keeps the route it held: the page says so, never silently shows the old plan as the new one.
function renderReadback(refused) {
  if (refused !== undefined) state.uploadRefused = refused;
  const el = $("#readback"), b = state.boatRoute, up = state.upload;
  let text = "the boat holds no route", cls = "";
  if (state.uploadRefused) {
    el.textContent = `${state.uploadRefused} — ${b && b.route ? `the old plan (route ${b.route_id || "?"}) is still active on the boat` : "the boat holds no route"}`;
    el.className = "readback bad"; state.readbackMatch = false; return;
  }
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
  const kind = FILE_KINDS[format];
  const blob = new Blob([res.text], { type: kind.mime });
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob);
  a.download = `route.${kind.suffix}`;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}
// lotsen's route files and the ground stations' (QGroundControl .plan, QGC WPL 110, KML, GPX)
const FILE_KINDS = {
  yaml: { suffix: "yaml", mime: "application/x-yaml" }, geojson: { suffix: "geojson", mime: "application/geo+json" },
  plan: { suffix: "plan", mime: "application/json" }, wpl: { suffix: "waypoints", mime: "text/plain" },
  kml: { suffix: "kml", mime: "application/vnd.google-earth.kml+xml" }, gpx: { suffix: "gpx", mime: "application/gpx+xml" },
};
function formatOf(name) {
  const m = /\.([a-z]+)$/i.exec(name); const ext = m ? m[1].toLowerCase() : "";
  return { yml: "yaml", yaml: "yaml", json: "geojson", geojson: "geojson", plan: "plan", waypoints: "wpl", wpl: "wpl",
           txt: "wpl", kml: "kml", gpx: "gpx" }[ext] || "yaml";
}
$("#btn-save-yaml").onclick = () => save("yaml");
$("#btn-save-geojson").onclick = () => save("geojson");
$("#btn-save-other").onclick = () => save($("#save-format").value);

$("#file-load").addEventListener("change", async ev => {
  const file = ev.target.files[0];
  ev.target.value = "";
  if (!file) return;
  const text = await file.text();
  const format = formatOf(file.name);
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

// MagCalibrationResult: the fit drawn over its raw samples (SVG, unit field = 1), residuals and
// coverage; a fresh fit is in use at once and waits for Accept / Reject (mag_accept / mag_reject)
function onMagcal(m) {
  state.magcal = m;
  const box = $("#magcal");
  box.hidden = false;
  const f = (x, d = 3) => (x == null ? "?" : x.toFixed(d));
  const decided = m.decision === "accepted" ? " — accepted" : m.decision === "rejected" ? " — rejected: the calibration in use before it is back" : m.ok ? " — in use, accept or reject it" : "";
  $("#magcal-text").textContent = m.ok
    ? `magnetometer calibration${decided}\nhard iron (centre) ${m.center.map(x => f(x, 2)).join(", ")} µT\n` +
      `soft iron [${m.matrix.map(r => r.map(x => f(x, 3)).join(" ")).join("; ")}] µT\n${m.text}`
    : `magnetometer calibration failed: ${m.text}`;
  $("#magcal-text").style.borderLeftColor = !m.ok || m.decision === "rejected" ? "#ef4c4c" : "#38c172";
  drawMagcal(m);
  if (m.ok && !m.decision) { toast("magnetometer calibrated: review the fit (Operate)"); alerts.clear("web:magcal", "a later calibration succeeded"); }
  else if (!m.ok) alerts.push({ severity: "error", code: "web:magcal", text: `magnetometer calibration failed: ${m.text}` });
  updateButtons();
}

function drawMagcal(m) {
  const svg = $("#magcal-plot"), pts = m.samples || [];
  if (!m.ok || !m.matrix || !pts.length) { svg.innerHTML = ""; $("#magcal-stats").textContent = ""; return; }
  const [[a, b], [c, d]] = m.matrix, [cx, cy] = m.center;
  const det = a * d - b * c, r = Math.sqrt(Math.abs(det)) || 1;
  const inv = [[d / det, -b / det], [-c / det, a / det]];
  // raw field in units of the mean field strength, centred on the fit; y up = east right
  const P = ([x, y]) => [(y - cy) / r, -(x - cx) / r];
  const res = pts.map(([x, y]) => { const u = x - cx, v = y - cy; return Math.hypot(inv[0][0] * u + inv[0][1] * v, inv[1][0] * u + inv[1][1] * v) - 1; });
  const ell = [];
  for (let k = 0; k <= 72; k++) { const t = 2 * Math.PI * k / 72; ell.push(P([cx + a * Math.cos(t) + b * Math.sin(t), cy + c * Math.cos(t) + d * Math.sin(t)])); }
  const rms = Math.sqrt(res.reduce((acc, x) => acc + x * x, 0) / res.length), worst = Math.max(...res.map(Math.abs));
  const dots = pts.map((p, i) => { const [x, y] = P(p); const bad = Math.abs(res[i]) > 3 * Math.max(rms, 1e-3);
    return `<circle cx="${x.toFixed(4)}" cy="${y.toFixed(4)}" r="0.025" class="${bad ? "bad" : ""}"/>`; }).join("");
  svg.innerHTML = `<line x1="-1.45" y1="0" x2="1.45" y2="0" class="axis"/><line x1="0" y1="-1.45" x2="0" y2="1.45" class="axis"/>` +
    `<polyline class="fit" points="${ell.map(([x, y]) => `${x.toFixed(4)},${y.toFixed(4)}`).join(" ")}"/>` +
    `<g class="samples">${dots}</g><text x="-1.45" y="-1.32" class="lbl">raw field / ${r.toFixed(1)} µT · fitted ellipse</text>`;
  svg.dataset.samples = String(pts.length);
  $("#magcal-stats").textContent = `${pts.length} samples shown · residual ${f3(m.residual)} (rms of |field| − 1, ` +
    `${(100 * rms).toFixed(1)} % here; worst ${(100 * worst).toFixed(1)} %) · coverage ${m.coverage_deg != null ? m.coverage_deg.toFixed(0) : "?"}° of 360°`;
}
function f3(x) { return x == null ? "?" : x.toFixed(3); }

// the detours of the active path: known when it is the route uploaded from a page of this server
function detoursOnPath() {
  const b = state.boatRoute, s = state.telemetry && state.telemetry.sup;
  if (!b || !state.uploadedId || b.route_id !== state.uploadedId || (s && s.mode === "RETURN")) return [];
  return state.uploadedDetours || [];
}

// -- parameter sheet (Settings tab): the model in use, planner limits (a few editable by the
// pilot, checked by the server), controller and failsafes
function onSettings(m) { state.settings = m; renderSettings(); }

// the QR code that pairs a second phone (pilot only): this page's own address with the credential
$("#btn-pair-qr").onclick = async () => {
  const res = await request({ type: "pair_qr", origin: location.origin });
  const box = $("#pair-qr");
  if (res.type !== "pair_qr") { alerts.push({ severity: "error", code: "web:pair", text: res.error || "no QR code" }); return; }
  box.innerHTML = `${res.svg}<p class="hint">scan with the phone's camera, or open ${esc(res.url)}</p>`;
  box.hidden = false;
};

function renderSettings() {
  const md = state.model;
  if (md) {
    const when = md.file_modified_utc ? ` (written ${md.file_modified_utc})` : "";
    $("#set-model").textContent = `${md.source === "default coefficients" ? "default coefficients (no parameter file)" : "parameter file " + md.source + when}` +
      (md.verdict === "predictive" ? " · identification verdict: predictive (effective coefficients: they predict this boat, they are not its physical values)"
        : md.verdict ? ` · identification verdict: ${md.verdict}` : " · no identification verdict") +
      (md.boat ? ` · simulated boat: ${md.boat}` : "");
    const rows = Object.entries(md.parameters || {}).map(([k, v]) => `<tr><td>${esc(k)}</td><td>${esc(fmtVal(v))}</td><td>${md.std && md.std[k] != null ? esc(fmtVal(md.std[k])) : ""}</td></tr>`).join("");
    const tb = $("#set-model-table tbody"); if (tb.innerHTML !== rows) tb.innerHTML = rows;
  }
  const st = state.settings;
  if (!st) return;
  $("#set-planner-why").textContent = `${state.pilot ? "You may change the marked limits (lower a speed or acceleration limit, raise the clearance)" : "Read-only: take the controls to change the marked limits"}; ` +
    `they take effect ${st.takes_effect}.` + (st.changes.length ? ` Changed: ${st.changes.map(c => `${c.name} ${c.from} → ${c.to}`).join(", ")}.` : "");
  const tb = $("#set-planner tbody");
  if (!tb.contains(document.activeElement)) {
    tb.innerHTML = Object.entries(st.planner).filter(([, r]) => r.editable).map(([k, r]) =>
      `<tr><td>${esc(r.label)}</td><td><input type="text" inputmode="decimal" data-param="planner.${k}" value="${r.value}" aria-label="${esc(r.label)} (${esc(r.unit)})" ${state.pilot ? "" : "readonly"}> ${esc(r.unit)}</td>` +
      `<td>${r.launch}</td><td>${r.lo}–${r.hi}</td></tr>`).join("");
  }
  const kv = (obj) => Object.entries(obj || {}).map(([k, v]) => `<tr><td>${esc(k)}</td><td>${esc(fmtVal(v))}</td></tr>`).join("");
  $("#set-planner-all tbody").innerHTML = Object.entries(st.planner).map(([k, r]) => `<tr><td>${esc(k)}</td><td>${esc(fmtVal(r.value))}</td></tr>`).join("");
  $("#set-controller tbody").innerHTML = kv(st.controller);
  $("#set-failsafes tbody").innerHTML = kv(st.failsafes);
}
function fmtVal(v) { return typeof v === "number" ? String(Math.round(v * 1e6) / 1e6) : Array.isArray(v) ? v.map(fmtVal).join(", ") : v && typeof v === "object" ? JSON.stringify(v) : String(v); }

$("#set-planner").addEventListener("change", async ev => {
  const inp = ev.target, name = inp.dataset.param;
  if (!name || !state.pilot) return;
  const t = inp.value.trim().replace(",", ".");
  const v = Number(t);
  if (t === "" || !Number.isFinite(v)) { setErr(inp, `${inp.getAttribute("aria-label")}: "${t.slice(0, 20)}" is not a number (not applied)`); return; }
  const res = await request({ type: "params", name, value: v });
  if (res.type === "params_ok") { setErr(inp, ""); inp.blur(); toast(`${inp.getAttribute("aria-label")}: ${v} — used from the next plan`); schedulePlan(); }
  else setErr(inp, `${res.error} (not applied)`);
});
function setErr(inp, text) {
  inp.classList.toggle("invalid", !!text); inp.setAttribute("aria-invalid", String(!!text));
  $("#set-err").textContent = text;
}

function showTab(name) {
  $$("#tabs .tab").forEach(x => x.classList.toggle("active", x.dataset.tab === name));
  $$(".tabpanel").forEach(p => { p.hidden = p.id !== `tab-${name}`; });
  if (name === "logs") refreshLogs();
  if (name === "maps") { suggestZooms(); refreshTiles(); }
}
$$("#tabs .tab").forEach(b => b.addEventListener("click", () => showTab(b.dataset.tab)));

$("#btn-sound").onclick = () => {
  const on = !alerts.sound;
  alerts.setSound(on);
  $("#btn-sound").textContent = on ? "sound on" : "sound off";
  $("#btn-sound").setAttribute("aria-pressed", String(on));
};

function placeToasts() {   // under the top bar: a toast never covers the mode and armed badges
  const b = $("#topbar").getBoundingClientRect().bottom;
  document.documentElement.style.setProperty("--toast-top", `${Math.round(b + 4)}px`);
}
window.addEventListener("resize", placeToasts);
new ResizeObserver(placeToasts).observe($("#topbar"));

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
