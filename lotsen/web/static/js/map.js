// Canvas map in local metres (north up, east right): offline tiles in Web Mercator underneath when
// cached (placed through the stack's geographic origin), a metre grid always. Draws the route
// being edited, the planner's draft path, the active path, the boat, its trail and the MPC
// prediction, and handles editing: place, insert (the + handles halfway along legs and polygon
// edges), drag, delete corners (select + Delete, or right-click), set bearing, pan, zoom.
import { bearingDeg, round2 } from "./route.js";

const HIT_PX = 10, HANDLE_PX = 34, PLUS_PX = 7;

export class MapView {
  constructor(canvas, route, opts = {}) {
    this.canvas = canvas;
    this.route = route;
    this.opts = opts;                 // {defaultSpeed(), onSelect(), onInfo(), onPan(), onPolygonDone(), onEdit()}
    this.tool = "select";
    this.n0 = 10; this.e0 = 10; this.scale = 14;   // view centre (m) and px per metre
    this.boat = null;                 // {n, e, psi}
    this.truth = null;
    this.trail = [];
    this.draftPath = null;            // {n: [], e: []}
    this.surveyLines = null;          // the draft survey's lines [[[n, e], [n, e]], ...] and polygon (plan result)
    this.surveyPolygon = null;
    this.coverage = null;             // {cell_m, cells: Map "i,j" -> [depth, count], holes: [[[n, e]...]], lo, hi}
    this.activePath = null;
    this.draftDetours = [];           // [{leg, s0, s1, length_m, straight_m}] on the draft path
    this.activeDetours = [];          // the same on the active path (when it is this page's upload)
    this.stale = false;               // no live data: the boat is drawn grey
    this.predicted = null;
    this.tiles = null;                // TileLayer
    this.origin = null;               // {lat, lon, h}
    this.follow = false;
    this.drag = null;
    this.dirty = true;
    this.cursor = null;
    this.hover = null;
    this.tilesDrawn = 0;
    this.bindEvents();
    const loop = () => { if (this.dirty) { this.dirty = false; this.draw(); } requestAnimationFrame(loop); };
    requestAnimationFrame(loop);
    new ResizeObserver(() => this.invalidate()).observe(canvas);
  }

  invalidate() { this.dirty = true; }

  // -- coordinates ------------------------------------------------------------------------------
  toScreen(n, e) {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    return [w / 2 + (e - this.e0) * this.scale, h / 2 - (n - this.n0) * this.scale];
  }
  toWorld(x, y) {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    return [this.n0 - (y - h / 2) / this.scale, this.e0 + (x - w / 2) / this.scale];
  }
  eventPos(ev) { const r = this.canvas.getBoundingClientRect(); return [ev.clientX - r.left, ev.clientY - r.top]; }
  // the visible box in local metres: [nMin, eMin, nMax, eMax]
  viewBox() {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    const [nTop, eLeft] = this.toWorld(0, 0), [nBot, eRight] = this.toWorld(w, h);
    return [nBot, eLeft, nTop, eRight];
  }

  fitPoints(pts, minSpan = 10) {
    if (!pts.length) pts = [[0, 0]];
    let nlo = Infinity, nhi = -Infinity, elo = Infinity, ehi = -Infinity;
    for (const [n, e] of pts) { nlo = Math.min(nlo, n); nhi = Math.max(nhi, n); elo = Math.min(elo, e); ehi = Math.max(ehi, e); }
    this.n0 = (nlo + nhi) / 2; this.e0 = (elo + ehi) / 2;
    const w = this.canvas.clientWidth || 800, h = this.canvas.clientHeight || 600;
    this.scale = Math.min(60, Math.max(0.5, 0.85 * Math.min(w / Math.max(ehi - elo, minSpan), h / Math.max(nhi - nlo, minSpan))));
    this.invalidate();
  }

  // everything: the route being edited, the boat's active path and the boat
  fit() {
    const pts = [];
    const r = this.route;
    if (r.harbour) pts.push([r.harbour.north, r.harbour.east]);
    r.nodes.forEach(n => pts.push([n.north, n.east]));
    if (r.area) pts.push(...r.area);
    if (r.survey && r.survey.polygon) pts.push(...r.survey.polygon);
    r.obstacles.forEach(o => pts.push(...o.polygon));
    const ap = this.activePath;
    if (ap && ap.n) for (let i = 0; i < ap.n.length; i += 10) pts.push([ap.n[i], ap.e[i]]);
    if (this.boat) pts.push([this.boat.n, this.boat.e]);
    this.fitPoints(pts);
  }

  // -- telemetry --------------------------------------------------------------------------------
  setBoat(pose, truth) {
    if (!pose || pose.n == null || pose.e == null) return;
    this.boat = { n: pose.n, e: pose.e, psi: pose.psi || 0 };
    this.truth = truth ? { n: truth.n, e: truth.e, psi: truth.psi } : null;
    const last = this.trail[this.trail.length - 1];
    if (!last || Math.hypot(pose.n - last[0], pose.e - last[1]) > 0.05) {
      this.trail.push([pose.n, pose.e]);
      if (this.trail.length > 4000) this.trail.splice(0, 1000);
    }
    if (this.follow) {
      const [x, y] = this.toScreen(pose.n, pose.e);
      const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
      if (x < w * 0.2 || x > w * 0.8 || y < h * 0.2 || y > h * 0.8) { this.n0 = pose.n; this.e0 = pose.e; }
    }
    this.invalidate();
  }

  // -- editing ----------------------------------------------------------------------------------
  setTool(tool) {
    if (this.route.drawing && tool !== this.route.drawing.kind) this.route.finishPolygon();
    this.tool = tool;
    if (tool === "area" || tool === "obstacle" || tool === "survey") this.route.startPolygon(tool);
    this.invalidate();
  }

  editing() { return this.tool === "select" || this.tool === "node" || this.tool === "harbour"; }

  // the "+" handles: halfway along each leg (insert a node) and each polygon edge (insert a corner)
  plusHandles() {
    const r = this.route, out = [];
    if (!this.editing()) return out;
    const chain = r.harbour ? [r.harbour, ...r.nodes] : [];
    for (let i = 1; i < chain.length; i++) {
      const a = chain[i - 1], b = chain[i];
      out.push({ kind: "insert", index: i - 1, n: (a.north + b.north) / 2, e: (a.east + b.east) / 2 });
    }
    const sel = r.selected && r.selected.kind === "vertex" ? r.selected.poly : null;
    for (const [which, poly] of r.polygons()) {
      if (which !== sel) continue;   // a polygon's edge handles once one of its corners is selected
      for (let k = 0; k < poly.length; k++) {
        const a = poly[k], b = poly[(k + 1) % poly.length];
        out.push({ kind: "vinsert", poly: which, k, n: (a[0] + b[0]) / 2, e: (a[1] + b[1]) / 2 });
      }
    }
    return out;
  }

  hit(x, y) {
    const r = this.route;
    const sel = r.point(r.selected);
    if (sel) {  // the bearing handle of the selected node
      const [hx, hy] = this.handlePos(sel);
      if (Math.hypot(x - hx, y - hy) < HIT_PX) return { kind: "heading", target: r.selected };
    }
    for (let i = r.nodes.length - 1; i >= 0; i--) {
      const [sx, sy] = this.toScreen(r.nodes[i].north, r.nodes[i].east);
      if (Math.hypot(x - sx, y - sy) < HIT_PX) return { kind: "node", index: i };
    }
    if (r.harbour) {
      const [sx, sy] = this.toScreen(r.harbour.north, r.harbour.east);
      if (Math.hypot(x - sx, y - sy) < HIT_PX + 2) return { kind: "harbour" };
    }
    for (const [which, poly] of r.polygons()) {
      for (let k = 0; k < poly.length; k++) {
        const [sx, sy] = this.toScreen(poly[k][0], poly[k][1]);
        if (Math.hypot(x - sx, y - sy) < HIT_PX) return { kind: "vertex", poly: which, k };
      }
    }
    for (const p of this.plusHandles()) {
      const [sx, sy] = this.toScreen(p.n, p.e);
      if (Math.hypot(x - sx, y - sy) < PLUS_PX + 2) return p;
    }
    return null;
  }

  handlePos(p) {
    const [sx, sy] = this.toScreen(p.north, p.east);
    const a = p.heading_deg * Math.PI / 180;
    return [sx + HANDLE_PX * Math.sin(a), sy - HANDLE_PX * Math.cos(a)];
  }

  bindEvents() {
    const c = this.canvas;
    c.addEventListener("contextmenu", ev => {
      ev.preventDefault();
      const [x, y] = this.eventPos(ev);
      const h = this.editing() ? this.hit(x, y) : null;
      if (h && h.kind === "vertex") this.route.deleteVertex(h.poly, h.k);   // right-click deletes a corner
    });
    // two fingers zoom and pan the map (never the page: the canvas has touch-action: none); a
    // second finger ends whatever the first one was doing, and nothing is placed when they lift
    this.pointers = new Map();
    const endPointer = ev => {
      this.pointers.delete(ev.pointerId);
      if (this.pinch && this.pointers.size < 2) { this.pinch = null; this.drag = null; this.pinchEnded = true; }
      if (this.pointers.size === 0) setTimeout(() => { this.pinchEnded = false; }, 0);
    };
    c.addEventListener("pointerdown", ev => {
      this.pointers.set(ev.pointerId, this.eventPos(ev));
      if (this.pointers.size === 2) {
        const [[x1, y1], [x2, y2]] = [...this.pointers.values()];
        const cx = (x1 + x2) / 2, cy = (y1 + y2) / 2;
        if (this.drag && this.drag.moved && this.drag.hit) this.route.commit();
        this.drag = null;
        this.pinch = { d0: Math.max(10, Math.hypot(x2 - x1, y2 - y1)), scale0: this.scale, world: this.toWorld(cx, cy) };
        this.follow = false;
        try { c.setPointerCapture(ev.pointerId); } catch (e) { /* synthetic */ }
        return;
      }
      if (this.pointers.size > 2 || this.pinch) return;
    });
    c.addEventListener("pointerdown", ev => {
      if (this.pinch || this.pointers.size > 1) return;
      c.focus();
      if (ev.button !== 0) return;
      const [x, y] = this.eventPos(ev);
      const h = this.editing() ? this.hit(x, y) : null;
      this.drag = { x0: x, y0: y, x, y, moved: false, hit: h, button: ev.button, n0: this.n0, e0: this.e0 };
      if (h && (h.kind === "node" || h.kind === "harbour" || h.kind === "vertex")) {
        this.route.selected = h; this.opts.onSelect && this.opts.onSelect();
      }
      c.setPointerCapture(ev.pointerId);
      this.invalidate();
    });
    c.addEventListener("pointermove", ev => {
      const [x, y] = this.eventPos(ev);
      if (this.pointers.has(ev.pointerId)) this.pointers.set(ev.pointerId, [x, y]);
      if (this.pinch) {
        if (this.pointers.size < 2) return;
        const [[x1, y1], [x2, y2]] = [...this.pointers.values()];
        const cx = (x1 + x2) / 2, cy = (y1 + y2) / 2;
        this.scale = Math.min(400, Math.max(0.05, this.pinch.scale0 * Math.hypot(x2 - x1, y2 - y1) / this.pinch.d0));
        const [n, e] = this.toWorld(cx, cy), [n0, e0] = this.pinch.world;   // the point under the fingers stays there
        this.n0 += n0 - n; this.e0 += e0 - e;
        this.opts.onPan && this.opts.onPan();
        this.invalidate();
        return;
      }
      this.cursor = this.toWorld(x, y);
      this.opts.onInfo && this.opts.onInfo(this.cursor);
      const d = this.drag;
      if (!d) {
        const h = this.editing() ? this.hit(x, y) : null;
        const key = h ? JSON.stringify(h) : null;
        if (key !== this.hover) { this.hover = key; c.style.cursor = h ? (h.kind === "insert" || h.kind === "vinsert" ? "copy" : "move") : ""; this.invalidate(); }
        if (this.route.drawing) this.invalidate();
        return;
      }
      if (Math.hypot(x - d.x0, y - d.y0) > 4) d.moved = true;
      if (!d.moved) return;
      const [n, e] = this.toWorld(x, y);
      const h = d.hit;
      if (h && h.kind === "heading") {
        const p = this.route.point(h.target);
        p.heading_deg = bearingDeg(p.north, p.east, n, e);
        this.route.changed(true, false);
      } else if (h && (h.kind === "node" || h.kind === "harbour")) {
        const p = this.route.point(h);
        p.north = round2(n); p.east = round2(e);
        this.route.changed(true, false);
      } else if (h && h.kind === "vertex") {
        const poly = this.route.polygon(h.poly);
        if (poly) { poly[h.k] = [round2(n), round2(e)]; this.route.changed(true, false); }
      } else if (!h) {  // pan
        this.n0 = d.n0 + (y - d.y0) / this.scale;
        this.e0 = d.e0 - (x - d.x0) / this.scale;
        this.follow = false;
        this.opts.onPan && this.opts.onPan();
      }
      this.invalidate();
    });
    c.addEventListener("pointercancel", endPointer);
    c.addEventListener("pointerup", ev => {
      const pinched = !!this.pinch || this.pinchEnded;
      endPointer(ev);
      const d = this.drag;
      this.drag = null;
      if (pinched || !d || d.button !== 0) return;
      if (d.moved) {   // the end of a drag is one undo step
        if (d.hit) { this.route.commit(); this.opts.onEdit && this.opts.onEdit(); }
        return;
      }
      const [x, y] = this.eventPos(ev);
      const [n, e] = this.toWorld(x, y).map(round2);
      const r = this.route;
      const h = d.hit;
      if (h && h.kind === "insert") r.insertNode(h.index, round2(h.n), round2(h.e));
      else if (h && h.kind === "vinsert") r.insertVertex(h.poly, h.k, round2(h.n), round2(h.e));
      else if (this.tool === "harbour") r.setHarbour(n, e);
      else if (this.tool === "node" && !h) r.addNode(n, e, this.opts.defaultSpeed ? this.opts.defaultSpeed() : 0.5);
      else if (this.tool === "area" || this.tool === "obstacle" || this.tool === "survey") {
        if (!r.drawing) r.startPolygon(this.tool);
        r.drawing.pts.push([n, e]);
        r.changed(false, false);
      } else if (this.tool === "select" && !h) { r.selected = null; this.opts.onSelect && this.opts.onSelect(); }
      this.invalidate();
    });
    c.addEventListener("dblclick", () => {
      if (this.route.drawing) { this.route.drawing.pts.pop(); this.route.finishPolygon(); this.opts.onPolygonDone && this.opts.onPolygonDone(); }
    });
    c.addEventListener("wheel", ev => {
      ev.preventDefault();
      const [x, y] = this.eventPos(ev);
      const [n, e] = this.toWorld(x, y);
      this.scale = Math.min(400, Math.max(0.05, this.scale * Math.exp(-ev.deltaY * 0.0015)));
      const [n2, e2] = this.toWorld(x, y);   // keep the point under the cursor fixed
      this.n0 += n - n2; this.e0 += e - e2;
      this.invalidate();
    }, { passive: false });
  }

  // -- drawing ----------------------------------------------------------------------------------
  draw() {
    const c = this.canvas, dpr = window.devicePixelRatio || 1;
    const w = c.clientWidth, h = c.clientHeight;
    if (!w || !h) return;
    if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) { c.width = Math.round(w * dpr); c.height = Math.round(h * dpr); }
    const g = c.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.fillStyle = "#0b1a2a"; g.fillRect(0, 0, w, h);
    this.tilesDrawn = this.tiles && this.origin ? this.tiles.draw(g, this, this.origin) : 0;
    this.drawGrid(g, w, h, this.tilesDrawn > 0);
    this.drawCoverage(g);
    this.drawRegions(g);
    this.drawSurvey(g);
    this.drawLine(g, this.activePath, "#38c172", 3, []);
    this.drawDetours(g, this.activePath, this.activeDetours);
    this.drawLine(g, this.draftPath, "#3fa7ff", 2, [8, 5]);
    this.drawDetours(g, this.draftPath, this.draftDetours);
    this.drawSpeeds(g, this.draftPath && this.draftPath.v ? this.draftPath : this.activePath, this.draftPath ? "#9fd2ff" : "#aef0c6");
    if (this.trail.length > 1) this.drawPolyline(g, this.trail, "rgba(255,216,74,0.85)", 2.5, []);
    this.drawLine(g, this.predicted, "#ff8c2e", 2.5, []);
    this.drawPlus(g);
    this.drawNodes(g);
    if (this.truth && !this.stale) this.drawBoat(g, this.truth, "rgba(255,255,255,0.35)");
    if (this.boat) this.drawBoat(g, this.boat, this.stale ? "#7a8591" : "#ffd84a");
    if (this.stale) {
      g.font = "bold 13px system-ui, sans-serif";
      const t = "no live data from the boat: positions are old";
      g.fillStyle = "rgba(40,44,50,0.85)"; g.fillRect(8, 8, g.measureText(t).width + 12, 22);
      g.fillStyle = "#c9d3dd"; g.fillText(t, 14, 24);
    }
    if (this.tilesDrawn && this.tiles.attribution) {
      g.font = "11px system-ui, sans-serif";
      const t = this.tiles.attribution, tw = g.measureText(t).width;
      g.fillStyle = "rgba(255,255,255,0.8)"; g.fillRect(w - tw - 12, h - 44, tw + 8, 15);
      g.fillStyle = "#222"; g.fillText(t, w - tw - 8, h - 33);
    }
  }

  drawGrid(g, w, h, overTiles) {
    const minPx = 50;
    const steps = [0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000];
    const step = steps.find(s => s * this.scale >= minPx) || 5000;
    const [nTop, eLeft] = this.toWorld(0, 0), [nBot, eRight] = this.toWorld(w, h);
    g.lineWidth = 1; g.font = "11px system-ui, sans-serif";
    const minor = overTiles ? "rgba(11,26,42,0.25)" : "#15304a", axis = overTiles ? "rgba(11,26,42,0.6)" : "#3d5a78";
    const label = overTiles ? "#0b1a2a" : "#5d7a96";
    for (let e = Math.ceil(eLeft / step) * step; e <= eRight; e += step) {
      const [x] = this.toScreen(0, e);
      g.strokeStyle = Math.abs(e) < 1e-9 ? axis : minor;
      g.beginPath(); g.moveTo(Math.round(x) + 0.5, 0); g.lineTo(Math.round(x) + 0.5, h); g.stroke();
      g.fillStyle = label; g.fillText(`E ${fmtM(e)}`, x + 3, h - 24);
    }
    for (let n = Math.ceil(nBot / step) * step; n <= nTop; n += step) {
      const [, y] = this.toScreen(n, 0);
      g.strokeStyle = Math.abs(n) < 1e-9 ? axis : minor;
      g.beginPath(); g.moveTo(0, Math.round(y) + 0.5); g.lineTo(w, Math.round(y) + 0.5); g.stroke();
      g.fillStyle = label; g.fillText(`N ${fmtM(n)}`, 4, y - 3);
    }
    // north arrow and scale bar (on a backing so they stay readable over tiles)
    g.fillStyle = "rgba(16,21,28,0.75)"; g.fillRect(w - 30 - step * this.scale, 46, step * this.scale + 24, 52);
    g.fillStyle = "#e3e9ef"; g.font = "bold 13px system-ui"; g.fillText("N ↑", w - 36, 62);
    const bar = step * this.scale;
    g.strokeStyle = "#e3e9ef"; g.lineWidth = 2;
    g.beginPath(); g.moveTo(w - 20 - bar, 78); g.lineTo(w - 20, 78); g.stroke();
    g.font = "11px system-ui"; g.fillText(`${fmtM(step)} m`, w - 20 - bar, 92);
  }

  polyPath(g, pts, close) {
    g.beginPath();
    pts.forEach((p, i) => { const [x, y] = this.toScreen(p[0], p[1]); if (i) g.lineTo(x, y); else g.moveTo(x, y); });
    if (close) g.closePath();
  }

  drawRegions(g) {
    const r = this.route;
    const sel = r.selected && r.selected.kind === "vertex" ? r.selected : null;
    if (r.area) {
      this.polyPath(g, r.area, true);
      g.fillStyle = "rgba(63,167,255,0.08)"; g.fill();
      g.strokeStyle = r.errorFor("area") ? "#ef4c4c" : "#3fa7ff"; g.lineWidth = 2; g.stroke();
      this.drawVertices(g, r.area, "#3fa7ff", sel && sel.poly === "area" ? sel.k : -1);
    }
    r.obstacles.forEach((o, i) => {
      this.polyPath(g, o.polygon, true);
      g.fillStyle = o.forbidden === "inside" ? "rgba(239,76,76,0.28)" : "rgba(239,76,76,0.08)"; g.fill();
      g.strokeStyle = r.errorFor("obstacle", i) ? "#ffffff" : "#ef4c4c"; g.lineWidth = 2; g.stroke();
      this.drawVertices(g, o.polygon, "#ef4c4c", sel && sel.poly === i ? sel.k : -1);
    });
    if (r.drawing && r.drawing.pts.length) {
      const pts = this.cursor ? [...r.drawing.pts, this.cursor] : r.drawing.pts;
      this.polyPath(g, pts, false);
      g.strokeStyle = r.drawing.kind === "area" ? "#3fa7ff" : r.drawing.kind === "survey" ? "#c8e64a" : "#ef4c4c"; g.setLineDash([5, 4]); g.lineWidth = 2; g.stroke(); g.setLineDash([]);
      this.drawVertices(g, r.drawing.pts, "#ffffff", -1);
    }
  }

  // the live coverage layer: each cell with soundings coloured by its mean depth (shallow light,
  // deep dark blue), the survey's holes outlined in red
  drawCoverage(g) {
    const c = this.coverage;
    if (!c || !c.cells.size) return;
    const span = Math.max(c.hi - c.lo, 0.1);
    for (const [key, [depth]] of c.cells) {
      const [i, j] = key.split(",").map(Number);
      const [x0, y0] = this.toScreen((i + 1) * c.cell_m, j * c.cell_m), [x1, y1] = this.toScreen(i * c.cell_m, (j + 1) * c.cell_m);
      const f = Math.min(1, Math.max(0, (depth - c.lo) / span));
      g.fillStyle = `rgba(${Math.round(170 - 150 * f)},${Math.round(230 - 150 * f)},255,0.55)`;
      g.fillRect(x0, y0, Math.max(1, x1 - x0), Math.max(1, y1 - y0));
    }
    for (const h of c.holes || []) {
      this.polyPath(g, h, true);
      g.strokeStyle = "#ff5a5a"; g.lineWidth = 2; g.setLineDash([3, 3]); g.stroke(); g.setLineDash([]);
    }
  }

  drawSurvey(g) {
    const s = this.route.survey;
    const poly = (s && s.polygon) || this.surveyPolygon;
    if (poly) {
      this.polyPath(g, poly, true);
      g.strokeStyle = "#c8e64a"; g.lineWidth = 2; g.setLineDash([6, 4]); g.stroke(); g.setLineDash([]);
      if (s && s.polygon) {
        const sel = this.route.selected && this.route.selected.kind === "vertex" && this.route.selected.poly === "survey" ? this.route.selected.k : -1;
        this.drawVertices(g, s.polygon, "#c8e64a", sel);
      }
    }
    if (this.surveyLines) {
      g.strokeStyle = "rgba(200,230,74,0.9)"; g.lineWidth = 1.5;
      for (const [a, b] of this.surveyLines) {
        const [x0, y0] = this.toScreen(a[0], a[1]), [x1, y1] = this.toScreen(b[0], b[1]);
        g.beginPath(); g.moveTo(x0, y0); g.lineTo(x1, y1); g.stroke();
      }
    }
  }

  drawVertices(g, pts, color, selected) {
    pts.forEach((p, k) => {
      const [x, y] = this.toScreen(p[0], p[1]);
      if (k === selected) { g.fillStyle = "#ffffff"; g.fillRect(x - 5, y - 5, 10, 10); }
      g.fillStyle = color; g.fillRect(x - 3, y - 3, 6, 6);
    });
  }

  drawPlus(g) {
    for (const p of this.plusHandles()) {
      const [x, y] = this.toScreen(p.n, p.e);
      g.beginPath(); g.arc(x, y, PLUS_PX - 1, 0, 2 * Math.PI);
      g.fillStyle = "rgba(16,21,28,0.75)"; g.fill();
      g.strokeStyle = p.kind === "insert" ? "#9fd2ff" : "#c9d3dd"; g.lineWidth = 1.5; g.stroke();
      g.beginPath(); g.moveTo(x - 3.5, y); g.lineTo(x + 3.5, y); g.moveTo(x, y - 3.5); g.lineTo(x, y + 3.5); g.stroke();
    }
  }

  drawLine(g, path, color, width, dash) {
    if (!path || !path.n || path.n.length < 2) return;
    g.beginPath();
    for (let i = 0; i < path.n.length; i++) {
      const [x, y] = this.toScreen(path.n[i], path.e[i]);
      if (i) g.lineTo(x, y); else g.moveTo(x, y);
    }
    g.strokeStyle = color; g.lineWidth = width; g.setLineDash(dash); g.stroke(); g.setLineDash([]);
  }

  // arc length along a drawn path (the planner's s when it came with one)
  static arcLength(path) {
    if (path.s && path.s.length === path.n.length) return path.s;
    const s = [0];
    for (let i = 1; i < path.n.length; i++) s.push(s[i - 1] + Math.hypot(path.n[i] - path.n[i - 1], path.e[i] - path.e[i - 1]));
    return s;
  }

  // the parts the planner routed round an obstacle or the area edge: orange over the path, labelled
  drawDetours(g, path, detours) {
    if (!path || !path.n || path.n.length < 2 || !detours || !detours.length) return;
    const s = MapView.arcLength(path);
    g.font = "bold 12px system-ui, sans-serif";
    for (const d of detours) {
      g.beginPath();
      let first = true, mid = null;
      for (let i = 0; i < s.length; i++) {
        if (s[i] < d.s0 || s[i] > d.s1) continue;
        const [x, y] = this.toScreen(path.n[i], path.e[i]);
        if (first) { g.moveTo(x, y); first = false; } else g.lineTo(x, y);
        if (mid === null && s[i] >= (d.s0 + d.s1) / 2) mid = [x, y];
      }
      g.strokeStyle = "#ff9f1a"; g.lineWidth = 5; g.setLineDash([6, 4]); g.stroke(); g.setLineDash([]);
      if (mid) { g.fillStyle = "#ff9f1a"; g.strokeStyle = "#0b1a2a"; g.lineWidth = 3; g.strokeText("detour", mid[0] + 8, mid[1] + 16); g.fillText("detour", mid[0] + 8, mid[1] + 16); }
    }
  }

  // the planned speed along the path: a label at least 90 px from the last, and where it changes
  drawSpeeds(g, path, color) {
    if (!path || !path.v || !path.n || path.n.length < 2) return;
    g.font = "11px system-ui, sans-serif";
    let last = null, lastV = null;
    this.speedLabels = 0;
    for (let i = 0; i < path.n.length; i++) {
      const v = path.v[i];
      if (v == null) continue;
      const [x, y] = this.toScreen(path.n[i], path.e[i]);
      const far = !last || Math.hypot(x - last[0], y - last[1]) > 90;
      const changed = lastV !== null && Math.abs(v - lastV) > 0.1 && (!last || Math.hypot(x - last[0], y - last[1]) > 45);
      if (!(far || changed)) continue;
      const t = `${v.toFixed(2)} m/s`;
      g.fillStyle = "rgba(11,26,42,0.75)"; g.fillRect(x + 4, y - 16, g.measureText(t).width + 6, 14);
      g.fillStyle = color; g.fillText(t, x + 7, y - 5);
      g.beginPath(); g.arc(x, y, 2, 0, 2 * Math.PI); g.fill();
      last = [x, y]; lastV = v; this.speedLabels++;
    }
  }

  drawPolyline(g, pts, color, width, dash) {
    this.polyPath(g, pts, false);
    g.strokeStyle = color; g.lineWidth = width; g.setLineDash(dash); g.stroke(); g.setLineDash([]);
  }

  drawNodes(g) {
    const r = this.route;
    const sel = r.selected;
    g.font = "bold 12px system-ui, sans-serif";
    const drawOne = (p, label, color, isSel, err) => {
      const [x, y] = this.toScreen(p.north, p.east);
      const a = p.heading_deg * Math.PI / 180;
      // bearing arrow
      g.strokeStyle = color; g.lineWidth = 2;
      g.beginPath(); g.moveTo(x, y); const [hx, hy] = [x + 22 * Math.sin(a), y - 22 * Math.cos(a)]; g.lineTo(hx, hy); g.stroke();
      g.beginPath(); g.moveTo(hx, hy);
      g.lineTo(hx - 7 * Math.sin(a - 0.5), hy + 7 * Math.cos(a - 0.5));
      g.lineTo(hx - 7 * Math.sin(a + 0.5), hy + 7 * Math.cos(a + 0.5)); g.closePath(); g.fillStyle = color; g.fill();
      g.beginPath(); g.arc(x, y, isSel ? 9 : 7, 0, 2 * Math.PI);
      g.fillStyle = err ? "#ef4c4c" : color; g.fill();
      g.lineWidth = isSel ? 3 : 1.5; g.strokeStyle = isSel ? "#ffffff" : "#0b1a2a"; g.stroke();
      g.fillStyle = "#ffffff"; g.strokeStyle = "#0b1a2a"; g.lineWidth = 3;
      g.strokeText(label, x + 10, y - 8); g.fillText(label, x + 10, y - 8);
      if (isSel) {
        const [qx, qy] = this.handlePos(p);
        g.beginPath(); g.arc(qx, qy, 6, 0, 2 * Math.PI); g.strokeStyle = "#ffffff"; g.lineWidth = 2; g.stroke();
      }
      if (err) {
        const text = err.message.length > 90 ? err.message.slice(0, 87) + "…" : err.message;
        g.font = "12px system-ui, sans-serif";
        const tw = g.measureText(text).width;
        g.fillStyle = "rgba(90,28,28,0.92)"; g.fillRect(x + 10, y + 4, tw + 8, 18);
        g.fillStyle = "#ffd0d0"; g.fillText(text, x + 14, y + 17);
        g.font = "bold 12px system-ui, sans-serif";
      }
    };
    if (r.harbour) drawOne(r.harbour, "H", "#c58bff", sel && sel.kind === "harbour", r.errorFor("harbour"));
    r.nodes.forEach((p, i) => drawOne(p, String(i + 1), "#3fa7ff", sel && sel.kind === "node" && sel.index === i, r.errorFor("node", i)));
  }

  drawBoat(g, b, color) {
    // hull outline in body coordinates (x forward, y starboard), metres: a 1 m boat
    const hull = [[0.55, 0], [0.3, 0.16], [-0.45, 0.16], [-0.45, -0.16], [0.3, -0.16]];
    const k = Math.max(1, 28 / (1.0 * this.scale));   // at least 28 px long on screen
    const c = Math.cos(b.psi), s = Math.sin(b.psi);
    g.beginPath();
    hull.forEach(([x, y], i) => {
      const n = b.n + k * (x * c - y * s), e = b.e + k * (x * s + y * c);
      const [sx, sy] = this.toScreen(n, e);
      if (i) g.lineTo(sx, sy); else g.moveTo(sx, sy);
    });
    g.closePath(); g.fillStyle = color; g.fill(); g.strokeStyle = "#000"; g.lineWidth = 1.5; g.stroke();
  }
}

function fmtM(x) { return Math.abs(x) < 1e-9 ? "0" : (Math.round(x * 10) / 10).toString(); }
