// The route being edited, in the planner's YAML schema (local NED metres, degrees).
export class RouteModel {
  constructor() {
    this.harbour = null;          // {north, east, heading_deg}
    this.nodes = [];              // [{north, east, heading_deg, speed_mps}]
    this.area = null;             // [[n, e], ...] navigable (outside forbidden)
    this.obstacles = [];          // [{polygon: [[n, e], ...], forbidden: "inside" | "outside"}]
    this.origin = null;           // geographic origin {lat_deg, lon_deg, height_m} of a loaded route
    this.drawing = null;          // polygon being drawn: {kind: "area" | "obstacle", pts: [[n, e]]}
    this.selected = null;         // {kind: "node", index} | {kind: "harbour"}
    this.errors = [];             // planner errors with {kind, index?, message}
    this.listeners = [];
  }

  onChange(fn) { this.listeners.push(fn); }
  changed(replan = true) { this.listeners.forEach(fn => fn(replan)); }

  complete() { return this.harbour !== null && this.nodes.length >= 1; }

  toDict() {
    const r = (x) => Math.round(x * 1000) / 1000;
    const d = {
      harbour: { north: r(this.harbour.north), east: r(this.harbour.east), heading_deg: r(this.harbour.heading_deg) },
      nodes: this.nodes.map(n => ({ north: r(n.north), east: r(n.east), heading_deg: r(n.heading_deg), speed_mps: r(n.speed_mps) })),
    };
    if (this.origin) d.origin = { ...this.origin };
    if (this.area) d.area = this.area.map(p => [r(p[0]), r(p[1])]);
    if (this.obstacles.length) d.obstacles = this.obstacles.map(o => ({ polygon: o.polygon.map(p => [r(p[0]), r(p[1])]), forbidden: o.forbidden }));
    return d;
  }

  fromDict(d) {
    this.harbour = d.harbour ? { north: d.harbour.north, east: d.harbour.east, heading_deg: d.harbour.heading_deg || 0 } : null;
    this.nodes = (d.nodes || []).map(n => ({ ...n }));
    this.origin = d.origin ? { ...d.origin } : null;
    this.area = d.area ? d.area.map(p => [p[0], p[1]]) : null;
    this.obstacles = (d.obstacles || []).map(o => Array.isArray(o) ? { polygon: o, forbidden: "inside" } : { polygon: o.polygon, forbidden: o.forbidden || "inside" });
    this.selected = null; this.drawing = null; this.errors = [];
    this.changed();
  }

  clear() {
    this.harbour = null; this.nodes = []; this.area = null; this.obstacles = []; this.origin = null;
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

  startPolygon(kind) { this.drawing = { kind, pts: [] }; this.changed(false); }

  finishPolygon() {
    const d = this.drawing;
    this.drawing = null;
    if (!d || d.pts.length < 3) { this.changed(false); return false; }
    if (d.kind === "area") this.area = d.pts; else this.obstacles.push({ polygon: d.pts, forbidden: "inside" });
    this.changed();
    return true;
  }

  errorFor(kind, index) {
    return this.errors.find(e => e.kind === kind && (index === undefined || e.index === index)) || null;
  }
}

export function bearingDeg(n0, e0, n1, e1) {
  const b = Math.atan2(e1 - e0, n1 - n0) * 180 / Math.PI;
  return Math.round(b * 10) / 10;
}
