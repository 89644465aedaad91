// Rolling strip chart on a canvas: a few series against time, autoscaled, no dependencies.
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
    if (this.t.length && t < this.t[this.t.length - 1]) { this.clear(); }  // server restarted
    this.t.push(t);
    values.forEach((v, i) => this.data[i].push(v == null || !isFinite(v) ? null : v));
    const tmin = t - this.windowS;
    let k = 0;
    while (k < this.t.length && this.t[k] < tmin) k++;
    if (k > 0) { this.t.splice(0, k); this.data.forEach(d => d.splice(0, k)); }
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
    let lo = Infinity, hi = -Infinity;
    for (const d of this.data) for (const v of d) if (v != null) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (!isFinite(lo)) { lo = -this.minSpan / 2; hi = this.minSpan / 2; }
    if (hi - lo < this.minSpan) { const m = (hi + lo) / 2; lo = m - this.minSpan / 2; hi = m + this.minSpan / 2; }
    const pad = 0.08 * (hi - lo); lo -= pad; hi += pad;
    const t1 = this.t.length ? this.t[this.t.length - 1] : 0, t0 = t1 - this.windowS;
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
    this.series.forEach((s, i) => {
      g.strokeStyle = s.color; g.lineWidth = 1.5; g.setLineDash(s.dash || []);
      g.beginPath();
      let pen = false;
      const d = this.data[i];
      for (let k = 0; k < d.length; k++) {
        if (d[k] == null) { pen = false; continue; }
        const x = X(this.t[k]), y = Y(d[k]);
        if (pen) g.lineTo(x, y); else { g.moveTo(x, y); pen = true; }
      }
      g.stroke(); g.setLineDash([]);
      g.fillStyle = s.color; g.fillText(s.label, lx, 12); lx += g.measureText(s.label).width + 8;
    });
    g.fillStyle = "#93a1b0"; g.fillText(`${this.windowS} s`, w - R - 28, h - 2);
  }
}

function niceStep(x) {
  const p = Math.pow(10, Math.floor(Math.log10(x || 1)));
  const m = x / p;
  return (m < 1.5 ? 1 : m < 3 ? 2 : m < 7 ? 5 : 10) * p;
}

function fmt(v, step) {
  const d = step >= 1 ? 0 : Math.min(3, Math.ceil(-Math.log10(step)));
  return (Math.abs(v) < step / 1e6 ? 0 : v).toFixed(d);
}
