// The route being edited, in the planner's YAML schema (local NED metres, degrees), with undo/redo.
export const LIMITS = {   // what the table accepts (the server checks again: validation.py, planning.io)
  north: [-2000, 2000, "m"], east: [-2000, 2000, "m"], heading_deg: [-360, 360, "deg"], speed_mps: [0, 1.5, "m/s"],
  lat: [-90, 90, "deg"], lon: [-180, 180, "deg"],
};
const NUMBER = /^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/;

// the operator's names of the fields (the table's heads), for messages
export const FIELD_WORDS = { north: "north", east: "east", heading_deg: "bearing", speed_mps: "speed", lat: "latitude", lon: "longitude" };

// Strict number from a table cell: {value} or {error} naming the problem in the operator's words
// (never a silent 0). The speed limit is the boat's (the server's planner limit, set from hello).
export function parseField(field, text) {
  const t = String(text).trim().replace(",", ".");
  const name = FIELD_WORDS[field] || field;
  if (t === "") return { error: `${name}: a number is required` };
  if (!NUMBER.test(t)) return { error: `${name}: "${t.slice(0, 20)}" is not a number` };
  const v = Number(t);
  const [lo, hi, unit] = LIMITS[field] || [-Infinity, Infinity, ""];
  if (field === "speed_mps" && Number.isFinite(v) && v > hi) return { error: `${name} ${t.slice(0, 20)} m/s exceeds the boat's ${hi} m/s` };
  if (!Number.isFinite(v) || v < lo || v > hi) return { error: `${name}: ${t.slice(0, 20)} ${unit} is outside ${lo} to ${hi} ${unit}` };
  return { value: field === "heading_deg" ? ((v % 360) + 360) % 360 : v };
}

const HISTORY_MAX = 200;
// a new survey's settings (the survey tool's fields change them; the boat's planner checks them again)
export const SURVEY_DEFAULTS = { spacing_m: 2.0, angle_deg: 0.0, speed_mps: 0.5, turnaround_m: 2.0, crosshatch: false };
export const SURVEY_LIMITS = { spacing_m: [0.1, 100, "m"], angle_deg: [-360, 360, "deg"], speed_mps: [0.05, 1.5, "m/s"], turnaround_m: [0, 100, "m"] };

export class RouteModel {
  constructor() {
    this.harbour = null;          // {north, east, heading_deg}
    this.nodes = [];              // [{north, east, heading_deg, speed_mps}]
    this.area = null;             // [[n, e], ...] navigable (outside forbidden)
    this.obstacles = [];          // [{polygon: [[n, e], ...], forbidden: "inside" | "outside"}]
    this.origin = null;           // geographic origin {lat_deg, lon_deg, height_m} of a loaded route
    this.survey = null;           // {polygon: [[n, e]] | null, lines?, spacing_m, angle_deg, speed_mps, turnaround_m, crosshatch}
    this.drawing = null;          // polygon being drawn: {kind: "area" | "obstacle", pts: [[n, e]]}
    this.selected = null;         // {kind: "node", index} | {kind: "harbour"} | {kind: "vertex", poly, k}
    this.errors = [];             // planner errors with {kind, index?, message}
    this.listeners = [];
    this.past = [this.snapshot()]; this.future = [];
  }

  onChange(fn) { this.listeners.push(fn); }
  // replan: ask the planner again; commit: record an undo step (false while dragging)
  changed(replan = true, commit = true) {
    if (commit) this.commit();
    this.listeners.forEach(fn => fn(replan));
  }

  // -- undo / redo ------------------------------------------------------------------------------
  snapshot() {
    return JSON.stringify({ h: this.harbour, n: this.nodes, a: this.area, o: this.obstacles, g: this.origin, s: this.survey });
  }
  restore(s) {
    const d = JSON.parse(s);
    this.harbour = d.h; this.nodes = d.n; this.area = d.a; this.obstacles = d.o; this.origin = d.g; this.survey = d.s || null;
    this.selected = null; this.drawing = null; this.errors = [];
  }
  commit() {
    const s = this.snapshot();
    if (s === this.past[this.past.length - 1]) return;
    this.past.push(s); this.future = [];
    if (this.past.length > HISTORY_MAX) this.past.shift();
  }
  canUndo() { return this.past.length > 1; }
  canRedo() { return this.future.length > 0; }
  undo() {
    if (!this.canUndo()) return false;
    this.future.push(this.past.pop());
    this.restore(this.past[this.past.length - 1]);
    this.changed(true, false);
    return true;
  }
  redo() {
    if (!this.canRedo()) return false;
    const s = this.future.pop();
    this.past.push(s);
    this.restore(s);
    this.changed(true, false);
    return true;
  }

  complete() { return this.harbour !== null && (this.nodes.length >= 1 || this.surveyReady()); }
  surveyReady() { return !!this.survey && (!!this.survey.polygon || !!this.survey.lines || !!this.area); }

  toDict() {
    const r = (x) => Math.round(x * 1000) / 1000;
    const d = {
      harbour: { north: r(this.harbour.north), east: r(this.harbour.east), heading_deg: r(this.harbour.heading_deg) },
    };
    if (this.survey) {   // a survey route: its nodes are made from the lines on the boat's planner
      const s = this.survey, out = {};
      for (const k of ["spacing_m", "angle_deg", "speed_mps", "turnaround_m", "turn_radius_m", "margin_m", "entry", "side"]) {
        if (s[k] !== undefined && s[k] !== null) out[k] = typeof s[k] === "number" ? r(s[k]) : s[k];
      }
      if (s.crosshatch) out.crosshatch = true;
      if (s.polygon) out.polygon = s.polygon.map(p => [r(p[0]), r(p[1])]);
      if (s.lines) out.lines = s.lines.map(l => [[r(l[0][0]), r(l[0][1])], [r(l[1][0]), r(l[1][1])]]);
      d.survey = out;
    } else {
      d.nodes = this.nodes.map(n => ({ north: r(n.north), east: r(n.east), heading_deg: r(n.heading_deg), speed_mps: r(n.speed_mps) }));
    }
    if (this.origin) d.origin = { ...this.origin };
    if (this.area) d.area = this.area.map(p => [r(p[0]), r(p[1])]);
    if (this.obstacles.length) d.obstacles = this.obstacles.map(o => ({ polygon: o.polygon.map(p => [r(p[0]), r(p[1])]), forbidden: o.forbidden }));
    return d;
  }

  fromDict(d) {
    this.harbour = d.harbour ? { north: d.harbour.north, east: d.harbour.east, heading_deg: d.harbour.heading_deg || 0 } : null;
    this.nodes = (d.nodes || []).map(n => ({ north: n.north, east: n.east, heading_deg: n.heading_deg, speed_mps: n.speed_mps }));
    this.survey = d.survey ? { ...SURVEY_DEFAULTS, ...d.survey } : null;
    this.origin = d.origin ? { ...d.origin } : null;
    this.area = d.area ? d.area.map(p => [p[0], p[1]]) : null;
    this.obstacles = (d.obstacles || []).map(o => Array.isArray(o) ? { polygon: o, forbidden: "inside" } : { polygon: o.polygon, forbidden: o.forbidden || "inside" });
    this.selected = null; this.drawing = null; this.errors = [];
    this.changed();
  }

  clear() {
    this.harbour = null; this.nodes = []; this.area = null; this.obstacles = []; this.origin = null; this.survey = null;
    this.drawing = null; this.selected = null; this.errors = [];
    this.changed();
  }

  // the harbour and the nodes go; the navigable area and the obstacles stay (the usual "Clear")
  clearNodes() {
    this.harbour = null; this.nodes = []; this.survey = null;
    this.drawing = null; this.selected = null; this.errors = [];
    this.changed();
  }

  setHarbour(n, e) {
    const h = this.harbour ? this.harbour.heading_deg : 0;
    this.harbour = { north: n, east: e, heading_deg: h };
    this.selected = { kind: "harbour" };
    this.changed();
  }

  addNode(n, e, speed) {
    const prev = this.nodes.length ? this.nodes[this.nodes.length - 1] : this.harbour;
    const hdg = prev ? bearingDeg(prev.north, prev.east, n, e) : 0;
    this.nodes.push({ north: n, east: e, heading_deg: hdg, speed_mps: speed });
    this.selected = { kind: "node", index: this.nodes.length - 1 };
    this.changed();
  }

  // a node before nodes[i] (i = nodes.length appends), at (n, e) or halfway along the chord
  insertNode(i, n, e) {
    const prev = i === 0 ? this.harbour : this.nodes[i - 1], next = this.nodes[i];
    if (!prev) return false;
    if (n === undefined) {
      if (!next) return false;
      n = round2((prev.north + next.north) / 2); e = round2((prev.east + next.east) / 2);
    }
    const hdg = next ? bearingDeg(prev.north, prev.east, next.north, next.east) : bearingDeg(prev.north, prev.east, n, e);
    const speeds = [prev.speed_mps, next && next.speed_mps].filter(v => v !== undefined && v > 0);
    const speed = speeds.length ? Math.round(speeds.reduce((a, b) => a + b, 0) / speeds.length * 100) / 100 : 0.5;
    this.nodes.splice(i, 0, { north: n, east: e, heading_deg: hdg, speed_mps: speed });
    this.selected = { kind: "node", index: i };
    this.changed();
    return true;
  }

  deleteNode(i) {
    this.nodes.splice(i, 1);
    this.selected = null;
    this.changed();
  }

  point(sel) {
    if (!sel) return null;
    if (sel.kind === "harbour") return this.harbour;
    if (sel.kind === "node") return this.nodes[sel.index] || null;
    return null;
  }

  // polygons: "area" or an obstacle index
  polygon(which) {
    if (which === "survey") return this.survey ? this.survey.polygon : null;
    return which === "area" ? this.area : (this.obstacles[which] ? this.obstacles[which].polygon : null);
  }
  polygons() {
    const out = [];
    if (this.area) out.push(["area", this.area]);
    if (this.survey && this.survey.polygon) out.push(["survey", this.survey.polygon]);
    this.obstacles.forEach((o, i) => out.push([i, o.polygon]));
    return out;
  }
  insertVertex(which, k, n, e) {   // after corner k
    const p = this.polygon(which);
    if (!p) return false;
    p.splice(k + 1, 0, [n, e]);
    this.selected = { kind: "vertex", poly: which, k: k + 1 };
    this.changed();
    return true;
  }
  deleteVertex(which, k) {
    const p = this.polygon(which);
    if (!p || p.length <= 3) return false;   // a polygon keeps at least 3 corners
    p.splice(k, 1);
    this.selected = null;
    this.changed();
    return true;
  }
  deletePolygon(which) {
    if (which === "area") this.area = null;
    else if (which === "survey") this.survey = null;
    else this.obstacles.splice(Number(which), 1);
    this.selected = null;
    this.changed();
  }

  startPolygon(kind) { this.drawing = { kind, pts: [] }; this.changed(false, false); }

  finishPolygon() {
    const d = this.drawing;
    this.drawing = null;
    if (!d || d.pts.length < 3) { this.changed(false, false); return false; }
    if (d.kind === "area") this.area = d.pts;
    else if (d.kind === "survey") { this.survey = { ...SURVEY_DEFAULTS, ...(this.survey || {}), polygon: d.pts, lines: undefined }; this.nodes = []; }
    else this.obstacles.push({ polygon: d.pts, forbidden: "inside" });
    this.changed();
    return true;
  }

  errorFor(kind, index) {
    return this.errors.find(e => e.kind === kind && (index === undefined || e.index === index)) || null;
  }
}

export function bearingDeg(n0, e0, n1, e1) {
  const b = Math.atan2(e1 - e0, n1 - n0) * 180 / Math.PI;
  return Math.round(((b % 360) + 360) % 360 * 10) / 10;
}
export function round2(x) { return Math.round(x * 100) / 100; }

// one form for comparisons: obstacles as {polygon, forbidden}, bearings in [0, 360), no origin
export function normalizeRoute(d) {
  if (!d || typeof d !== "object") return d;
  const hdg = (x) => (typeof x === "number" ? ((x % 360) + 360) % 360 : x);
  const out = { harbour: d.harbour ? { ...d.harbour, heading_deg: hdg(d.harbour.heading_deg) } : d.harbour,
    nodes: (d.nodes || []).map(n => ({ ...n, heading_deg: hdg(n.heading_deg) })) };
  if (d.survey) {   // with the defaults the boat fills in, so a page's draft and the boat's read-back compare equal
    const s = { ...SURVEY_DEFAULTS, margin_m: 0.5, ...d.survey };
    for (const k of Object.keys(s)) if (s[k] === null || s[k] === undefined || s[k] === false) delete s[k];
    out.survey = s;
  }
  if (d.area) out.area = d.area;
  const obs = (d.obstacles || []).map(o => Array.isArray(o) ? { polygon: o, forbidden: "inside" } : { polygon: o.polygon, forbidden: o.forbidden || "inside" });
  if (obs.length) out.obstacles = obs;
  return out;
}

// differences between two route dicts (the upload and the boat's read-back), [] when equal
export function routeDiff(a, b, tol = 1e-6) {
  a = normalizeRoute(a); b = normalizeRoute(b);
  const out = [];
  const walk = (x, y, path) => {
    if (out.length > 5) return;
    if (typeof x === "number" && typeof y === "number") {
      let d = Math.abs(x - y);
      if (path.endsWith("heading_deg")) d = Math.min(d, 360 - d);
      if (d > tol) out.push(`${path}: ${x} vs ${y}`);
      return;
    }
    if (Array.isArray(x) && Array.isArray(y)) {
      if (x.length !== y.length) { out.push(`${path}: ${x.length} vs ${y.length} items`); return; }
      x.forEach((v, i) => walk(v, y[i], `${path}[${i}]`)); return;
    }
    if (x && y && typeof x === "object" && typeof y === "object") {
      const keys = new Set([...Object.keys(x), ...Object.keys(y)]);
      for (const k of keys) if (k !== "origin") walk(x[k], y[k], path ? `${path}.${k}` : k);
      return;
    }
    if (x !== y && !(x == null && y == null)) out.push(`${path}: ${JSON.stringify(x)} vs ${JSON.stringify(y)}`);
  };
  walk(a, b, "");
  return out;
}

// legs much longer than the others (a typo: north 500 for 50): [{leg, length_m, median_m}]; a leg
// counts when it is over `factor` times the median of the other legs and `min_extra_m` longer
export function longLegs(route, factor = 3, minExtraM = 20) {
  const chain = route.harbour ? [route.harbour, ...route.nodes] : [];
  const lens = [];
  for (let i = 1; i < chain.length; i++) lens.push(Math.hypot(chain[i].north - chain[i - 1].north, chain[i].east - chain[i - 1].east));
  if (lens.length < 2) return [];
  const out = [];
  lens.forEach((L, i) => {
    const others = lens.filter((_, j) => j !== i).sort((a, b) => a - b);
    const m = others.length % 2 ? others[(others.length - 1) / 2] : (others[others.length / 2 - 1] + others[others.length / 2]) / 2;
    if (L > factor * m && L - m > minExtraM) {
      out.push({ leg: i === 0 ? "the leg from the harbour to node 1" : `the leg from node ${i} to node ${i + 1}`, length_m: L, median_m: m });
    }
  });
  return out;
}
