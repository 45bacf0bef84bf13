// Teleoperation input: keyboard and the Gamepad API, as stick deflections in the drone's
// own frame (forward, right, up; -1..1). While any input is held the current deflection
// is sent `rateHz` times a second; on release, on blur or when the page is hidden, one
// "stop" is sent and nothing more. The server rotates moves into North/East and
// rate-limits them again.
const KEYS = {
  KeyW: ["forward", 1], ArrowUp: ["forward", 1],
  KeyS: ["forward", -1], ArrowDown: ["forward", -1],
  KeyD: ["right", 1], ArrowRight: ["right", 1],
  KeyA: ["right", -1], ArrowLeft: ["right", -1],
  KeyR: ["up", 1], PageUp: ["up", 1],
  KeyF: ["up", -1], PageDown: ["up", -1],
};
const DEADZONE = 0.15;

function deadzone(value) {
  return Math.abs(value) < DEADZONE ? 0 : Math.max(-1, Math.min(1, value));
}

export class Teleop {
  constructor({ send, rateHz = 4, onChange = () => {} }) {
    this.send = send;
    this.period = 1000 / rateHz;
    this.onChange = onChange;
    this.enabled = false;
    this.held = new Set();
    this.moving = false;
    this.timer = null;
    window.addEventListener("keydown", (event) => this.key(event, true));
    window.addEventListener("keyup", (event) => this.key(event, false));
    // Away from the page (another window, another tab) nothing is sent, even with a
    // gamepad stick still deflected, until the page has the focus again.
    this.focused = true;
    window.addEventListener("blur", () => {
      this.focused = false;
      this.release();
    });
    window.addEventListener("focus", () => {
      this.focused = true;
    });
    document.addEventListener("visibilitychange", () => {
      if (document.hidden) this.release();
    });
  }

  setEnabled(enabled) {
    this.enabled = enabled;
    if (enabled && !this.timer) {
      this.timer = setInterval(() => this.tick(), this.period);
    } else if (!enabled) {
      clearInterval(this.timer);
      this.timer = null;
      this.release();
    }
    this.onChange(this.enabled);
  }

  key(event, down) {
    if (!this.enabled || !(event.code in KEYS)) return;
    if (event.target instanceof HTMLInputElement || event.target instanceof HTMLSelectElement) return;
    event.preventDefault();
    if (down) this.held.add(event.code);
    else this.held.delete(event.code);
    this.tick();
  }

  release() {
    this.held.clear();
    if (this.moving) {
      this.moving = false;
      this.send({ type: "stop" });
    }
  }

  stick() {
    const input = { forward: 0, right: 0, up: 0 };
    for (const code of this.held) {
      const [axis, sign] = KEYS[code];
      input[axis] = Math.max(-1, Math.min(1, input[axis] + sign));
    }
    const pads = navigator.getGamepads ? navigator.getGamepads() : [];
    for (const pad of pads) {
      if (!pad || !pad.connected) continue;
      // Standard mapping: left stick moves, right stick's vertical axis climbs.
      input.forward = input.forward || -deadzone(pad.axes[1] ?? 0);
      input.right = input.right || deadzone(pad.axes[0] ?? 0);
      input.up = input.up || -deadzone(pad.axes[3] ?? 0);
    }
    return input;
  }

  tick() {
    if (!this.enabled || !this.focused || document.hidden) return;
    const input = this.stick();
    const active = input.forward !== 0 || input.right !== 0 || input.up !== 0;
    if (active) {
      const now = performance.now();
      if (!this.lastSent || now - this.lastSent >= this.period * 0.9) {
        this.lastSent = now;
        this.moving = true;
        this.send({ type: "teleop", ...input });
      }
    } else if (this.moving) {
      this.release();
    }
  }
}
