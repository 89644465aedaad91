// Manual driving: held keys, held buttons of the on-screen pad (one per finger) and a gamepad's
// sticks -> ManualCommand axes, sent at 10 Hz while anything is held and once as zero when the
// last one is released, the window loses focus or the tab is hidden.
const AXES = {
  KeyW: ["surge", 1, "w"], ArrowUp: ["surge", 1, "w"],
  KeyS: ["surge", -1, "s"], ArrowDown: ["surge", -1, "s"],
  KeyA: ["yaw", -1, "a"], ArrowLeft: ["yaw", -1, "a"],
  KeyD: ["yaw", 1, "d"], ArrowRight: ["yaw", 1, "d"],
  KeyQ: ["sway", -1, "q"], KeyE: ["sway", 1, "e"],
};
export const PERIOD_MS = 100;

export class KeyboardDriver {
  // send(cmd) transmits {surge, sway, yaw}; enabled() says whether driving is allowed now;
  // onChange(keys, cmd) updates the indicator; onEstop() is the Esc key outside a text field
  // (inside one, Esc cancels the edit).
  constructor({ send, enabled, gain, onChange, onEstop }) {
    this.send = send; this.enabled = enabled; this.gain = gain; this.onChange = onChange; this.onEstop = onEstop;
    this.held = new Map();   // who holds (a key code, "pad<pointerId>") -> the AXES key it drives
    this.analog = null;      // a gamepad's {surge, sway, yaw} in [-1, 1] while its dead-man is held
    this.spaceFlash = false;
    this.timer = null;
    this.editStart = new WeakMap();  // a field's value when it got the focus: what Esc restores
    document.addEventListener("focusin", ev => {
      if (this.field(ev.target) || (ev.target && ev.target.type === "range")) this.editStart.set(ev.target, ev.target.value);
    });
    window.addEventListener("keydown", ev => this.keydown(ev));
    window.addEventListener("keyup", ev => this.keyup(ev));
    window.addEventListener("blur", () => this.stop());
    document.addEventListener("visibilitychange", () => { if (document.hidden) this.stop(); });
  }

  field(t) {
    return !!t && (t.tagName === "INPUT" || t.tagName === "TEXTAREA" || t.tagName === "SELECT" || t.isContentEditable)
      && t.type !== "range" && t.type !== "checkbox" && t.type !== "button";
  }

  typing(ev) { return this.field(ev.target); }

  command() {
    const c = { surge: 0, sway: 0, yaw: 0 };
    for (const code of this.held.values()) { const [axis, sign] = AXES[code]; c[axis] += sign; }
    if (this.analog) for (const k of Object.keys(c)) c[k] += this.analog[k];
    const g = this.gain();
    for (const k of Object.keys(c)) c[k] = Math.max(-1, Math.min(1, c[k])) * g;
    return c;
  }

  keys() {
    const s = new Set([...this.held.values()].map(code => AXES[code][2]));
    if (this.spaceFlash) s.add("space");
    return s;
  }

  keydown(ev) {
    if (ev.code === "Escape") {
      ev.preventDefault();
      this.stop();
      // the habit "Esc cancels this edit": restore the field (or the gain slider), never stop the boat
      if (this.typing(ev) || (ev.target && ev.target.type === "range")) {
        const t = ev.target;
        if (this.editStart.has(t) && t.value !== this.editStart.get(t)) {
          t.value = this.editStart.get(t);
          t.dispatchEvent(new Event("input", { bubbles: true }));
        }
        t.blur();
        return;
      }
      this.onEstop();
      return;
    }
    if (this.typing(ev)) return;
    if (ev.code === "Space") {
      ev.preventDefault();
      this.spaceFlash = true; setTimeout(() => { this.spaceFlash = false; this.onChange(this.keys(), this.command()); }, 300);
      this.stop();
      return;
    }
    if (!(ev.code in AXES)) return;
    ev.preventDefault();
    if (ev.repeat || this.held.has(ev.code)) return;
    this.press(ev.code, ev.code);
  }

  keyup(ev) { this.release(ev.code); }

  // `who` holds `code` (a key of AXES) until release(who); false when driving is not allowed now
  press(who, code) {
    if (!(code in AXES)) return false;
    if (!this.enabled()) { this.onChange(this.keys(), this.command(), "take the controls (pilot token) to drive"); return false; }
    this.held.set(who, code);
    this.run();
    return true;
  }

  release(who) {
    if (!this.held.delete(who)) return;
    if (this.held.size === 0 && !this.analog) this.stop(); else this.tick();
  }

  // a gamepad's axes while its dead-man button is held; null when released (then a stop)
  setAnalog(a) {
    if (a && !this.enabled()) a = null;
    const had = !!this.analog;
    this.analog = a;
    if (a) this.run();
    else if (had && this.held.size === 0) this.stop();
  }

  run() {
    this.tick();
    if (!this.timer) this.timer = setInterval(() => this.tick(), PERIOD_MS);
  }

  tick() {
    if (!this.enabled()) { this.stop(); return; }
    const c = this.command();
    this.send(c);
    this.onChange(this.keys(), c);
  }

  stop() {
    const wasDriving = this.held.size > 0 || this.timer !== null || !!this.analog;
    this.held.clear();
    this.analog = null;
    if (this.timer) { clearInterval(this.timer); this.timer = null; }
    const zero = { surge: 0, sway: 0, yaw: 0 };
    if (this.enabled() && (wasDriving || this.spaceFlash)) this.send(zero);
    this.onChange(this.keys(), zero);
  }
}
