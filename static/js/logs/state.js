// One time cursor, one visible window and one selected interval per log: every view of
// the viewer listens here, so they stay in sync.

export class TimeState extends EventTarget {
  constructor(start, end) {
    super();
    this.start = start;
    this.end = end > start ? end : start + 1;
    this.view = [this.start, this.end];
    this.cursor = this.start;
    this.selection = null;
  }

  on(type, handler) {
    this.addEventListener(type, (event) => handler(event.detail));
  }

  emit(type, detail) {
    this.dispatchEvent(new CustomEvent(type, { detail }));
  }

  clamp(t) {
    return Math.min(Math.max(t, this.start), this.end);
  }

  setCursor(t, source = "user") {
    const value = this.clamp(t);
    if (value === this.cursor && source !== "force") return;
    this.cursor = value;
    this.emit("cursor", { t: value, source });
  }

  setView(a, b) {
    const span = this.end - this.start;
    const minSpan = Math.max(span * 1e-6, 1e-4);
    let width = Math.min(Math.max(b - a, minSpan), span);
    let lo = Math.max(this.start, Math.min(a, this.end - width));
    const hi = lo + width;
    if (lo === this.view[0] && hi === this.view[1]) return;
    this.view = [lo, hi];
    this.emit("view", { view: this.view });
  }

  zoom(factor, around = (this.view[0] + this.view[1]) / 2) {
    const [a, b] = this.view;
    this.setView(around - (around - a) * factor, around + (b - around) * factor);
  }

  pan(dt) {
    const [a, b] = this.view;
    this.setView(a + dt, b + dt);
  }

  setSelection(a, b) {
    if (a === null || a === undefined) {
      if (this.selection === null) return;
      this.selection = null;
    } else {
      const lo = this.clamp(Math.min(a, b));
      const hi = this.clamp(Math.max(a, b));
      this.selection = hi > lo ? [lo, hi] : null;
    }
    this.emit("selection", { selection: this.selection });
  }

  /** Seconds since the log's first sample. */
  rel(t) {
    return t - this.start;
  }
}

export function formatDuration(seconds, digits = 3) {
  const sign = seconds < 0 ? "−" : "";
  let s = Math.abs(seconds);
  const h = Math.floor(s / 3600);
  s -= h * 3600;
  const m = Math.floor(s / 60);
  s -= m * 60;
  const sec = s.toFixed(digits).padStart(digits ? digits + 3 : 2, "0");
  return h ? `${sign}${h}:${String(m).padStart(2, "0")}:${sec}` : `${sign}${String(m).padStart(2, "0")}:${sec}`;
}

export function throttle(fn, ms) {
  let last = 0;
  let timer = null;
  let pending = null;
  return (...args) => {
    pending = args;
    const now = performance.now();
    const wait = last + ms - now;
    if (wait <= 0) {
      last = now;
      fn(...pending);
    } else if (!timer) {
      timer = setTimeout(() => {
        timer = null;
        last = performance.now();
        fn(...pending);
      }, wait);
    }
  };
}

export function debounce(fn, ms) {
  let timer = null;
  return (...args) => {
    clearTimeout(timer);
    timer = setTimeout(() => fn(...args), ms);
  };
}

export const PALETTE = ["#2358d6", "#e4572e", "#17a673", "#9b51e0", "#f2a900", "#00a6c8", "#c2185b", "#6d7a00", "#8d6e63", "#455a64"];
