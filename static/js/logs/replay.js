// Replay: the cursor advances in real time (times the speed) through the whole log, or only
// through the selected interval when there is one; every view follows the cursor.

export class Replay {
  constructor(viewer, { playButton, speedSelect }) {
    this.viewer = viewer;
    this.state = viewer.state;
    this.playButton = playButton;
    this.speedSelect = speedSelect;
    this.playing = false;
    this.frame = null;
    this.origin = null;
  }

  range() {
    return this.state.selection || [this.state.start, this.state.end];
  }

  toggle() {
    if (this.playing) this.pause();
    else this.play();
  }

  play() {
    const [a, b] = this.range();
    if (this.state.cursor < a || this.state.cursor >= b) this.state.setCursor(a, "replay");
    this.origin = this.state.cursor;
    this.playing = true;
    this.update();
    let last = performance.now();
    const step = (now) => {
      if (!this.playing) return;
      const speed = Number(this.speedSelect.value) || 1;
      const [lo, hi] = this.range();
      const next = Math.min(this.state.cursor + ((now - last) / 1000) * speed, hi);
      last = now;
      this.state.setCursor(Math.max(next, lo), "replay");
      this.follow();
      if (next >= hi) this.pause();
      else this.frame = requestAnimationFrame(step);
    };
    this.frame = requestAnimationFrame(step);
  }

  pause() {
    this.playing = false;
    cancelAnimationFrame(this.frame);
    this.update();
  }

  /** Stop and go back to where this replay started. */
  stop() {
    this.pause();
    this.state.setCursor(this.origin ?? this.range()[0], "replay");
    this.follow();
  }

  rewind() {
    this.state.setCursor(this.range()[0], "replay");
    this.follow();
  }

  /** Keep the cursor in the visible window, paging forward like a chart recorder. */
  follow() {
    const [a, b] = this.state.view;
    const t = this.state.cursor;
    if (t < a || t > b) {
      const width = b - a;
      this.state.setView(t - width * 0.1, t + width * 0.9);
    }
  }

  update() {
    this.playButton.setAttribute("aria-label", this.playing ? "Pause" : "Play");
    this.viewer.root.classList.toggle("playing", this.playing);
  }
}
