// Rolling strip chart on a canvas: a few series against time, autoscaled, no dependencies.
// Keeps up to HISTORY_S of data (10 Hz); the window shown is selectable (windowS); long windows
// are drawn with one min/max pair per pixel column.
export const HISTORY_S = 900;
const MIN_DT = 0.095;

export class StripChart {
  // series: [{label, color, dash}]; opts: {title, unit, windowS, minSpan}
  constructor(canvas, series, opts = {}) {
    this.canvas = canvas;
    this.series = series;
    this.title = opts.title || "";
    this.unit = opts.unit || "";
    this.windowS = opts.windowS || 60;
    this.minSpan = opts.minSpan || 1;
    this.t = [];
    this.data = series.map(() => []);
  }

  push(t, values) {
    if (t == null) return;
    const last = this.t.length ? this.t[this.t.length - 1] : null;
    if (last !== null && t < last) { this.clear(); }  // server restarted
    else if (last !== null && t - last < MIN_DT) return;
    this.t.push(t);
    values.forEach((v, i) => this.data[i].push(v == null || !isFinite(v) ? null : v));
    if (this.t.length > 200 && this.t[0] < t - HISTORY_S - 30) {   // trim in chunks
      const k = lowerBound(this.t, t - HISTORY_S);
      this.t.splice(0, k); this.data.forEach(d => d.splice(0, k));
    }
  }

  clear() { this.t = []; this.data = this.series.map(() => []); }

  draw() {
    const c = this.canvas, dpr = window.devicePixelRatio || 1;
    const w = c.clientWidth, h = c.clientHeight;
    if (!w || !h) return;
    if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) {
      c.width = Math.round(w * dpr); c.height = Math.round(h * dpr);
    }
    const g = c.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    const L = 38, R = 6, T = 18, B = 14;
    const t1 = this.t.length ? this.t[this.t.length - 1] : 0, t0 = t1 - this.windowS;
    const i0 = lowerBound(this.t, t0);
    let lo = Infinity, hi = -Infinity;
    for (const d of this.data) for (let k = i0; k < d.length; k++) { const v = d[k]; if (v != null) { if (v < lo) lo = v; if (v > hi) hi = v; } }
    if (!isFinite(lo)) { lo = -this.minSpan / 2; hi = this.minSpan / 2; }
    if (hi - lo < this.minSpan) { const m = (hi + lo) / 2; lo = m - this.minSpan / 2; hi = m + this.minSpan / 2; }
    const pad = 0.08 * (hi - lo); lo -= pad; hi += pad;
    const X = t => L + (t - t0) / this.windowS * (w - L - R);
    const Y = v => T + (hi - v) / (hi - lo) * (h - T - B);
    g.font = "11px system-ui, sans-serif";
    g.strokeStyle = "#2c3744"; g.fillStyle = "#93a1b0"; g.lineWidth = 1;
    const step = niceStep((hi - lo) / 4);
    for (let v = Math.ceil(lo / step) * step; v <= hi; v += step) {
      const y = Math.round(Y(v)) + 0.5;
      g.beginPath(); g.moveTo(L, y); g.lineTo(w - R, y); g.stroke();
      g.fillText(fmt(v, step), 2, y + 4);
    }
    if (lo < 0 && hi > 0) { g.strokeStyle = "#4a5a6c"; g.beginPath(); g.moveTo(L, Y(0)); g.lineTo(w - R, Y(0)); g.stroke(); }
    g.fillStyle = "#e3e9ef";
    g.fillText(`${this.title}${this.unit ? " (" + this.unit + ")" : ""}`, L, 12);
    let lx = L + g.measureText(this.title + " (" + this.unit + ")").width + 10;
    const n = this.t.length - i0, cols = Math.max(1, Math.floor(w - L - R));
    this.series.forEach((s, i) => {
      g.strokeStyle = s.color; g.lineWidth = 1.5; g.setLineDash(s.dash || []);
      g.beginPath();
      const d = this.data[i];
      if (n > 2 * cols) this.traceMinMax(g, d, i0, X, Y, L, cols, t0);
      else {
        let pen = false;
        for (let k = i0; k < d.length; k++) {
          if (d[k] == null) { pen = false; continue; }
          const x = X(this.t[k]), y = Y(d[k]);
          if (pen) g.lineTo(x, y); else { g.moveTo(x, y); pen = true; }
        }
      }
      g.stroke(); g.setLineDash([]);
      g.fillStyle = s.color; g.fillText(s.label, lx, 12); lx += g.measureText(s.label).width + 8;
    });
    g.fillStyle = "#93a1b0"; g.fillText(fmtWindow(this.windowS), w - R - 34, h - 2);
  }

  traceMinMax(g, d, i0, X, Y, L, cols, t0) {   // one vertical min-max stroke per pixel column
    let col = -1, vmin = 0, vmax = 0, have = false, started = false;
    const flush = () => {
      if (!have) return;
      const x = L + col + 0.5;
      if (started) g.lineTo(x, Y(vmax)); else { g.moveTo(x, Y(vmax)); started = true; }
      g.lineTo(x, Y(vmin) + 0.5);
    };
    for (let k = i0; k < d.length; k++) {
      const v = d[k];
      if (v == null) continue;
      const c = Math.floor(X(this.t[k]) - L);
      if (c !== col) { flush(); col = c; vmin = vmax = v; have = true; }
      else { if (v < vmin) vmin = v; if (v > vmax) vmax = v; }
    }
    flush();
  }
}

function lowerBound(a, x) { let lo = 0, hi = a.length; while (lo < hi) { const m = (lo + hi) >> 1; if (a[m] < x) lo = m + 1; else hi = m; } return lo; }

function niceStep(x) {
  const p = Math.pow(10, Math.floor(Math.log10(x || 1)));
  const m = x / p;
  return (m < 1.5 ? 1 : m < 3 ? 2 : m < 7 ? 5 : 10) * p;
}

function fmt(v, step) {
  const d = step >= 1 ? 0 : Math.min(3, Math.ceil(-Math.log10(step)));
  return (Math.abs(v) < step / 1e6 ? 0 : v).toFixed(d);
}
function fmtWindow(s) { return s >= 60 ? `${s / 60} min` : `${s} s`; }
