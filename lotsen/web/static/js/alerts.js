// Alerts: refusals, failsafes and warnings as visible messages, most severe first, each
// dismissable; the same code replaces its older message; a cleared condition (active=false)
// removes it. Optional sound (Web Audio tones, nothing loaded): critical three beeps, error two,
// warning one. Info messages fade after a few seconds.
export const SEVERITY = ["info", "warning", "error", "critical"];
const INFO_TTL_MS = 8000, MAX_SHOWN = 6;

export class AlertCenter {
  constructor(box, opts = {}) {
    this.box = box;
    this.opts = opts;            // {onChange()}
    this.items = new Map();      // code -> {severity, code, text, t, count, received}
    this.dismissed = new Map();  // code -> text dismissed (shown again when the text or severity changes)
    this.sound = false;
    this.audio = null;
    box.addEventListener("click", ev => {
      const code = ev.target.dataset && ev.target.dataset.dismiss;
      if (code !== undefined) this.dismiss(code);
    });
    setInterval(() => this.expire(), 1000);
  }

  // {severity, code, text, active, t, source}
  push(a) {
    const code = a.code || `local:${a.text}`;
    if (a.active === false) {   // the condition cleared
      const had = this.items.delete(code);
      this.dismissed.delete(code);
      if (had) this.render();
      return;
    }
    const sev = SEVERITY.includes(a.severity) ? a.severity : "warning";
    const old = this.items.get(code);
    const same = old && old.text === a.text && old.severity === sev;
    if (this.dismissed.get(code) === `${sev}|${a.text}` && (!old || same)) return;   // the operator dismissed it
    this.items.set(code, { severity: sev, code, text: a.text, t: a.t, count: same ? old.count + 1 : 1, received: Date.now() });
    if (!same) this.beep(sev);
    this.render();
  }

  // the cause cleared (seen by the page): the alert goes, the Events list keeps the history
  clear(code, why = "") {
    const it = this.items.get(code);
    this.dismissed.delete(code);
    if (!it) return false;
    this.items.delete(code);
    this.render();
    this.opts.onCleared && this.opts.onCleared(it, why);
    return true;
  }

  dismiss(code) {
    const it = this.items.get(code);
    if (it) this.dismissed.set(code, `${it.severity}|${it.text}`);
    this.items.delete(code);
    this.render();
  }

  expire() {
    const now = Date.now();
    let changed = false;
    for (const [code, it] of this.items) if (it.severity === "info" && now - it.received > INFO_TTL_MS) { this.items.delete(code); changed = true; }
    if (changed) this.render();
  }

  sorted() {
    return [...this.items.values()].sort((a, b) => SEVERITY.indexOf(b.severity) - SEVERITY.indexOf(a.severity) || b.received - a.received);
  }

  render() {
    const list = this.sorted();
    const shown = list.slice(0, MAX_SHOWN);
    this.box.innerHTML = shown.map(a =>
      `<div class="alert ${a.severity}" role="${a.severity === "info" ? "status" : "alert"}" data-code="${esc(a.code)}">` +
      `<span class="sev">${a.severity}</span><span class="text">${esc(a.text)}${a.count > 1 ? ` <span class="count">×${a.count}</span>` : ""}</span>` +
      `<button type="button" class="dismiss" data-dismiss="${esc(a.code)}" title="dismiss" aria-label="dismiss">✕</button></div>`).join("") +
      (list.length > MAX_SHOWN ? `<div class="alert more">+ ${list.length - MAX_SHOWN} more (Events tab)</div>` : "");
    this.opts.onChange && this.opts.onChange(list);
  }

  // -- sound -------------------------------------------------------------------------------------
  setSound(on) {
    this.sound = on;
    if (on && !this.audio) {
      const Ctx = window.AudioContext || window.webkitAudioContext;
      this.audio = Ctx ? new Ctx() : null;   // created on the click that enabled it (autoplay rules)
    }
    if (on && this.audio && this.audio.state === "suspended") this.audio.resume();   // a browser may start it suspended
  }

  beep(sev) {
    if (!this.sound || !this.audio || sev === "info") return;
    const n = { warning: 1, error: 2, critical: 3 }[sev], f = { warning: 660, error: 880, critical: 1100 }[sev];
    const t0 = this.audio.currentTime;
    for (let i = 0; i < n; i++) {
      const o = this.audio.createOscillator(), gain = this.audio.createGain();
      o.frequency.value = f; o.type = "square";
      gain.gain.setValueAtTime(0.0001, t0 + i * 0.25);
      gain.gain.exponentialRampToValueAtTime(0.15, t0 + i * 0.25 + 0.02);
      gain.gain.exponentialRampToValueAtTime(0.0001, t0 + i * 0.25 + 0.18);
      o.connect(gain).connect(this.audio.destination);
      o.start(t0 + i * 0.25); o.stop(t0 + i * 0.25 + 0.2);
    }
    this.beeps = (this.beeps || 0) + 1;
  }
}

export function esc(s) { return String(s).replace(/[&<>"']/g, c => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]); }
