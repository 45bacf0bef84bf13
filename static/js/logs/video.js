// The flight's recorded video on the log's time axis (GET /api/v1/logs/{id}/video/; the
// mission log viewer uses it too, one panel per drone, static/js/missions_log_time.js): the
// video follows the viewer's cursor — seeking while the cursor is moved, playing at the
// replay's speed while it replays — and each shown frame's capture time, drawn into the
// frame (onboard/framecode.py, read by static/js/live_video.js), ties the video's own
// time to the log's clock. A recording's file time is when the ground received each
// frame; the capture time read from the frame corrects that by the link's delay.

const HEADER_ROWS = 16; // the framecode strip: 2 rows of 8 pixels
// WebM times are whole milliseconds (livevideo/recording.py TIME_BASE): half of one tells
// a frame's own time from the time just before it.
const EPS_S = 0.0005;
const DRIFT_S = 0.3; // while replaying, a video this far from the cursor is moved to it
// A paused seek lands on the frame whose file time (the ground's receive time) holds the
// target, and receive times do not follow capture times frame for frame: each landing's
// captured time narrows the frames the due one can be (the last captured at or before the
// cursor), so the search ends on it after at most one seek per frame of the recording, a
// few to find the end of a long one, however slowly each frame decodes.
const EXTRA_SEEKS = 16;
// After a seek the element may still show the frame presented before it (a loaded browser
// presents the sought frame later): a picture unchanged by a seek is taken as the seek's
// only when no new frame is presented within this time.
const SAME_FRAME_WAIT_MS = 1000;
// A seek that nothing answered within this time (no `seeked`, no frame presented, or a
// frame whose stamp could not be read) is made again, up to the search's bound; past it
// the picture shown stays, so a search always ends.
const STALL_MS = 3000;

export class VideoPanel {
  constructor(card, viewer, url) {
    this.card = card;
    this.viewer = viewer;
    this.state = viewer.state;
    this.url = url;
    this.video = card.querySelector("video");
    this.caption = card.querySelector('[data-part="video-caption"]');
    this.canvas = document.createElement("canvas");
    this.context = this.canvas.getContext("2d", { willReadFrequently: true });
    this.recordings = [];
    this.current = null;
    this.search = null; // the paused seek under way (see land)
    this.presented = null; // the capture time (ms) of the frame last presented
    this.seeks = 0; // seeks made, so a wait knows whether a later seek superseded it
  }

  async load() {
    const response = await fetch(this.url, { credentials: "same-origin", headers: { Accept: "application/json" } });
    if (!response.ok) return;
    const body = await response.json();
    this.use(body.recordings);
  }

  /** Play these recordings (as the video endpoints describe them) in step with the cursor. */
  use(recordings) {
    this.recordings = recordings.map((r) => ({
      ...r,
      start: Date.parse(r.started_at) / 1000,
      end: Date.parse(r.ended_at) / 1000,
      shift: Date.parse(r.started_at) / 1000, // log time = video time + shift, until a frame is read
      times: new Map(), // captured ms → the frame's own file time, for each frame presented
    }));
    if (!this.recordings.length) return;
    this.card.hidden = false;
    this.card.dataset.recordings = String(this.recordings.length);
    this.video.muted = true;
    // Only a presented frame's own media time (requestVideoFrameCallback) sets the shift;
    // after a seek the element's time is the target, somewhere inside the frame shown.
    this.video.addEventListener("seeked", () => this.readFrame(this.video.currentTime, false));
    this.watchFrames();
    this.state.on("cursor", ({ source }) => this.follow(source));
    this.follow("load");
  }

  /** The recording that covers log time t, if any. */
  recordingAt(t) {
    return this.recordings.find((r) => t >= r.start && t <= r.end) || null;
  }

  follow(source) {
    const t = this.state.cursor;
    const recording = this.recordingAt(t);
    if (!recording) {
      this.video.pause();
      this.card.dataset.state = "outside";
      this.caption.textContent = "No video at this time.";
      return;
    }
    if (this.current !== recording) {
      this.current = recording;
      this.video.src = recording.file;
    }
    const target = Math.max(0, t - recording.shift);
    const replaying = this.viewer.replay && this.viewer.replay.playing && source === "replay";
    if (replaying) {
      this.video.playbackRate = Math.min(Math.max(Number(this.viewer.replay.speedSelect.value) || 1, 0.0625), 16);
      this.search = null;
      if (this.video.paused) this.video.play().catch(() => {});
      if (Math.abs(this.video.currentTime - target) > DRIFT_S) this.seek(target);
      this.card.dataset.state = "playing";
    } else {
      this.video.pause();
      this.search = { cursor: t, lo: null, hi: null, step: 0, seeks: 0, due: null };
      this.card.dataset.state = "seeking";
      this.seek(target);
    }
  }

  seek(target) {
    this.seeks += 1;
    if (this.search) {
      this.search.target = target;
      this.search.landed = false;
    }
    if (this.video.readyState >= 1) this.video.currentTime = target;
    else this.video.addEventListener("loadedmetadata", () => { this.video.currentTime = target; }, { once: true });
    this.watchStall();
  }

  watchStall() {
    const seeks = this.seeks;
    setTimeout(() => {
      const search = this.search;
      if (this.seeks !== seeks || !search || this.card.dataset.state !== "seeking") return;
      search.seeks += 1;
      if (search.seeks <= this.seekBound()) {
        this.seek(this.beside(search.target));
        return;
      }
      this.card.dataset.state = "shown";
      this.search = null;
    }, STALL_MS);
  }

  watchFrames() {
    if (!this.video.requestVideoFrameCallback) return;
    const each = (_now, metadata) => {
      this.video.requestVideoFrameCallback(each); // first: a failed read must not end the chain
      this.readFrame(metadata.mediaTime, true);
    };
    this.video.requestVideoFrameCallback(each);
  }

  /** Read the capture time of the frame shown at video time `mediaTime`: with `exact`
   *  (a presented frame's own media time) it is that frame's file time. */
  readFrame(mediaTime, exact, settled = false) {
    const reader = window.SkyhiveLiveVideo;
    const width = this.video.videoWidth;
    const recording = this.current;
    if (!reader || !width || !recording) return;
    if (this.canvas.width !== width) { this.canvas.width = width; this.canvas.height = HEADER_ROWS; }
    this.context.drawImage(this.video, 0, 0, width, HEADER_ROWS, 0, 0, width, HEADER_ROWS);
    const captured = reader.readStamp(this.context.getImageData(0, 0, width, HEADER_ROWS).data, width);
    if (captured === null) return;
    if (exact || !this.video.requestVideoFrameCallback) this.pair(recording, captured, mediaTime);
    const again = !exact && captured === this.presented; // no new presentation will come
    if (exact) this.presented = captured;
    if (this.video.seeking) return; // the frame shown is not yet the seek's
    if (again && !settled && this.video.requestVideoFrameCallback) {
      this.awaitPresentation(mediaTime);
      return;
    }
    if (this.card.dataset.state === "outside") return; // a frame late for a cursor moved off it
    const time = recording.times.get(captured);
    const search = this.search;
    if (time === undefined) {
      // Its presentation callback tells its own time; when that callback's reading was
      // distrusted, or the picture did not change (no callback comes), the frame is
      // presented again by seeking to it once more.
      if ((exact || again) && search && !search.landed && this.card.dataset.state === "seeking") {
        search.seeks += 1;
        // An unchanged picture gets no new presentation by seeking to it again: a
        // neighbouring frame is sought first, and the search comes back from there.
        if (search.seeks <= this.seekBound()) this.seek(again ? this.beside(search.target) : search.target);
      }
      return;
    }
    recording.shift = captured / 1000 - time;
    this.card.dataset.frameMs = String(captured);
    this.caption.textContent = `Frame captured ${new Date(captured).toISOString().slice(11, 23)} UTC`;
    if (search && this.card.dataset.state === "seeking" && !search.landed) {
      search.landed = true;
      this.land(search, { captured: captured / 1000, time });
    }
  }

  /** A seek left the picture unchanged: read it as the seek's frame unless a frame is
   *  presented (and read) first, or another seek supersedes this one. */
  awaitPresentation(mediaTime) {
    const seeks = this.seeks;
    const presented = this.presented;
    setTimeout(() => {
      if (this.seeks === seeks && this.presented === presented && !this.video.seeking) {
        this.readFrame(mediaTime, false, true);
      }
    }, SAME_FRAME_WAIT_MS);
  }

  /** Remember that the frame captured at `captured` (ms) has file time `time`. Frames
   *  are filed in the order they were captured, one time each: a reading out of that
   *  order with those known (a callback's time read beside another frame's picture, as a
   *  loaded browser may draw) is distrusted with the ones it contradicts, and each of
   *  those frames is timed again when next presented. */
  pair(recording, captured, time) {
    let consistent = true;
    for (const [other, known] of recording.times) {
      if (other === captured && Math.abs(known - time) <= EPS_S) continue;
      const before = other < captured, earlier = known < time - EPS_S, later = known > time + EPS_S;
      if (other === captured || (before ? !earlier : !later)) {
        recording.times.delete(other);
        consistent = false;
      }
    }
    if (consistent) recording.times.set(captured, time);
  }

  /** A paused seek landed on `frame` (its capture and file times): narrow the frames
   *  the due one can be, and seek again, or show it. */
  land(search, frame) {
    search.seeks += 1;
    const { cursor } = search;
    const due = search.due !== null && Math.abs(search.due.time - frame.time) <= EPS_S;
    if (due || search.seeks > this.seekBound()) {
      this.card.dataset.state = "shown";
      this.search = null;
      return;
    }
    search.due = null;
    if (frame.captured <= cursor + EPS_S) {
      // Captured in time: the due frame is this one or a later one; the next frame
      // starts after the target that landed here.
      if (!search.lo || frame.time > search.lo.time + EPS_S) {
        search.lo = { ...frame, after: search.target };
        search.step = 0;
      } else {
        search.lo.after = Math.max(search.lo.after, search.target);
      }
    } else if (!search.hi || frame.time < search.hi.time - EPS_S) {
      search.hi = { ...frame, before: search.target };
    } else {
      search.hi.before = Math.min(search.hi.before, search.target);
    }
    const next = this.nextTarget(search);
    if (typeof next === "number") {
      this.seek(next);
      return;
    }
    // `next` is the due frame: shown now, or sought by its own time.
    if (Math.abs(next.time - frame.time) <= EPS_S) {
      this.card.dataset.state = "shown";
      this.search = null;
    } else {
      search.due = next;
      this.seek(next.time + EPS_S / 2);
    }
  }

  /** The file time to seek to next, or the due frame when the search is over. */
  nextTarget(search) {
    const { lo, hi, cursor } = search;
    const duration = Number.isFinite(this.video.duration) ? this.video.duration : Infinity;
    if (hi && !lo) {
      // Every frame seen is after the cursor: one before the earliest, unless a target
      // before its own time landed on it (no frame before it).
      if (hi.before < hi.time - EPS_S || hi.time <= EPS_S) return hi;
      return Math.max(0, Math.min(hi.time - (hi.captured - cursor), hi.time - EPS_S));
    }
    if (lo && hi) {
      // The frame after `lo` starts after lo.after; `hi` starts at hi.time: nothing
      // between them is left unseen once the two are within a millisecond.
      if (hi.time - lo.after <= 2 * EPS_S) return lo;
      const guess = lo.time + (cursor - lo.captured);
      return guess > lo.after + EPS_S && guess < hi.time - EPS_S ? guess : hi.time - EPS_S;
    }
    // Only frames in time so far: find the first one after the cursor, or the file's end.
    if (lo.after >= duration - EPS_S) return lo;
    const guess = lo.time + (cursor - lo.captured);
    if (guess > lo.after + EPS_S) return Math.min(guess, duration);
    search.step = search.step ? 2 * search.step : this.frameInterval();
    return Math.min(lo.after + search.step, duration);
  }

  /** The recording's mean time between frames (s). */
  frameInterval() {
    const r = this.current;
    return r && r.frames > 1 ? (r.end - r.start) / r.frames : 0.1;
  }

  /** Seeks one paused seek may take: one per frame, and the probes for the file's end. */
  /** A file time one frame's length from `target`, inside the recording. */
  beside(target) {
    const duration = Number.isFinite(this.video.duration) ? this.video.duration : 0;
    const frames = this.current ? this.current.frames : 0;
    if (!duration || !frames) return target;
    const step = duration / frames;
    return target + step < duration ? target + step : Math.max(0, target - step);
  }

  seekBound() {
    return (this.current ? this.current.frames : 0) + EXTRA_SEEKS;
  }
}
