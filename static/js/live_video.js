// Live video (docs/video.md) on the drone page, the video wall, teleoperation and the
// mission page (which switches the player to the drone selected): WHEP through the portal,
// the capture time drawn into each frame (onboard/framecode.py) read back to show the
// glass-to-glass delay.
(function () {
  "use strict";

  var CELLS_PER_ROW = 32, CELL_HEIGHT = 8, TIME_BITS = 48, CHECK_BITS = 16;
  var THRESHOLD = (16 + 235) / 2;
  var POLL_MS = 2000, GATHER_MS = 2000, DELAYS_KEPT = 15;

  function crc16(bytes) { // CRC-16/CCITT-FALSE, as onboard/framecode.py
    var crc = 0xffff;
    for (var i = 0; i < bytes.length; i++) {
      crc ^= bytes[i] << 8;
      for (var b = 0; b < 8; b++) {
        crc = (crc & 0x8000) ? ((crc << 1) ^ 0x1021) & 0xffff : (crc << 1) & 0xffff;
      }
    }
    return crc;
  }

  // The capture time (ms since the epoch) in the top rows of RGBA pixels, or null.
  function readStamp(pixels, width) {
    var cell = Math.floor(width / CELLS_PER_ROW);
    if (cell < 4) return null;
    var bits = [];
    for (var index = 0; index < TIME_BITS + CHECK_BITS; index++) {
      var row = Math.floor(index / CELLS_PER_ROW), column = index % CELLS_PER_ROW;
      var y = row * CELL_HEIGHT + CELL_HEIGHT / 2;
      var x0 = column * cell + Math.floor(cell / 4), x1 = column * cell + Math.floor(3 * cell / 4);
      var sum = 0, n = 0;
      for (var yy = y - 1; yy < y + 1; yy++) {
        for (var x = x0; x < Math.max(x1, x0 + 1); x++) {
          var p = (yy * width + x) * 4;
          sum += 0.299 * pixels[p] + 0.587 * pixels[p + 1] + 0.114 * pixels[p + 2];
          n++;
        }
      }
      bits.push(sum / n > THRESHOLD ? 1 : 0);
    }
    var bytes = [];
    for (var i = 0; i < 6; i++) {
      var byte = 0;
      for (var j = 0; j < 8; j++) byte = (byte << 1) | bits[i * 8 + j];
      bytes.push(byte);
    }
    var check = 0;
    for (var k = TIME_BITS; k < TIME_BITS + CHECK_BITS; k++) check = (check << 1) | bits[k];
    if (crc16(bytes) !== check) return null;
    var ms = 0;
    for (var m = 0; m < 6; m++) ms = ms * 256 + bytes[m];
    return ms;
  }

  function median(values) {
    var sorted = values.slice().sort(function (a, b) { return a - b; });
    return sorted[Math.floor(sorted.length / 2)];
  }

  function csrf() {
    var meta = document.querySelector('meta[name="csrf-token"]');
    return meta ? meta.content : "";
  }

  function Player(card) {
    this.card = card;
    this.video = card.querySelector("video");
    this.stateUrl = card.dataset.videoUrl;
    this.canvas = document.createElement("canvas");
    this.context = this.canvas.getContext("2d", { willReadFrequently: true });
    this.pc = null;
    this.session = null;
    this.delays = [];
    this.clockOffset = 0; // server clock minus this browser's, ms
    this.frames = 0;
    this.lastBytes = null;
    this.timer = null;
  }

  Player.prototype.show = function (name, text) {
    var field = this.card.querySelector('[data-video="' + name + '"]');
    if (field) field.textContent = text;
  };

  Player.prototype.setState = function (state) {
    this.card.dataset.state = state;
    var badge = this.card.querySelector('[data-video="state"]');
    if (!badge) return;
    badge.textContent = state;
    badge.className = "badge " + (state === "playing" ? "ok" : "off");
  };

  // Why a drone has no stream, as the portal says it (not_live).
  var NOT_LIVE = {
    media_server_unavailable: "The media server does not answer.",
    drone_offline: "This drone is offline.",
    not_publishing: "This drone is online but is not streaming live video now.",
  };

  // Why there is no picture, in words, for cards that have a place for it.
  Player.prototype.explain = function (text) {
    this.card.dataset.why = text;
    this.show("why", text);
  };

  Player.prototype.poll = function () {
    var self = this;
    var asked = Date.now();
    var url = this.stateUrl;
    if (!url) return;
    fetch(url, { credentials: "same-origin", headers: { Accept: "application/json" } })
      .then(function (r) {
        if (r.ok) return r.json();
        return r.json().catch(function () { return {}; }).then(function (body) {
          return { refused: r.status, detail: body.detail };
        });
      })
      .then(function (state) {
        if (url !== self.stateUrl) return; // another drone was chosen meanwhile
        if (state.refused) {
          self.setState("unavailable");
          self.explain(state.refused === 404 ? "This drone is not one of your organisation's." : (state.detail || "Refused (" + state.refused + ")."));
          return;
        }
        var now = Date.now();
        self.clockOffset = state.server_time_ms - (asked + now) / 2;
        self.watchUrl = state.watch_url;
        self.maxDelay = state.teleop_max_delay_ms;
        if (state.media_server === "unavailable" && !self.pc) {
          self.setState("unavailable");
          self.explain(NOT_LIVE.media_server_unavailable);
          return;
        }
        if (state.live && !self.pc) self.connect();
        if (!state.live && !self.pc) {
          self.setState("not streaming");
          self.explain(NOT_LIVE[state.not_live] || "This drone is not streaming live video now.");
        }
      })
      .catch(function () { if (url === self.stateUrl) self.setState("unavailable"); })
      .then(function () {
        if (url === self.stateUrl) self.timer = setTimeout(function () { self.poll(); }, POLL_MS);
      });
  };

  // Play another drone's stream in this card (the mission page's selected drone).
  Player.prototype.watch = function (stateUrl) {
    if (stateUrl === this.stateUrl) return;
    clearTimeout(this.timer);
    this.stateUrl = stateUrl;
    this.card.dataset.videoUrl = stateUrl;
    this.drop();
    this.video.srcObject = null;
    this.delays = [];
    this.frames = 0;
    this.lastBytes = null;
    ["frames", "captured", "delayMs", "bitrateKbps", "why", "error"].forEach(function (key) {
      delete this.card.dataset[key];
    }, this);
    ["delay", "resolution", "bitrate"].forEach(function (name) { this.show(name, "–"); }, this);
    this.show("why", "");
    this.setState("connecting");
    this.poll();
  };

  Player.prototype.connect = function () {
    var self = this;
    var pc = new RTCPeerConnection();
    this.pc = pc;
    this.setState("connecting");
    pc.addTransceiver("video", { direction: "recvonly" });
    pc.ontrack = function (event) {
      self.video.srcObject = event.streams && event.streams[0] ? event.streams[0] : new MediaStream([event.track]);
      self.video.play().catch(function () {});
    };
    pc.onconnectionstatechange = function () {
      if (pc.connectionState === "failed" || pc.connectionState === "closed") self.drop();
    };
    var watchUrl = this.watchUrl;
    pc.createOffer()
      .then(function (offer) { return pc.setLocalDescription(offer); })
      .then(function () { return gathered(pc); })
      .then(function () {
        if (self.pc !== pc) throw new Error("switched");
        return fetch(watchUrl, {
          method: "POST",
          credentials: "same-origin",
          headers: { "Content-Type": "application/sdp", "X-CSRFToken": csrf() },
          body: pc.localDescription.sdp,
        });
      })
      .then(function (response) {
        if (response.status !== 201) {
          return response.json().catch(function () { return {}; }).then(function (body) {
            throw new Error("refused " + response.status + (body.detail ? ": " + body.detail : ""));
          });
        }
        if (self.pc !== pc) { // another drone was chosen meanwhile: end this session
          endSession(response.headers.get("Location"));
          throw new Error("switched");
        }
        self.session = response.headers.get("Location");
        return response.text();
      })
      .then(function (answer) { return pc.setRemoteDescription({ type: "answer", sdp: answer }); })
      .then(function () { self.watchFrames(pc); })
      .catch(function (error) {
        if (self.pc !== pc) { pc.close(); return; }
        self.setState("refused");
        self.card.dataset.error = String(error);
        self.explain("No viewer session: " + String(error.message || error) + ".");
        self.drop();
      });
  };

  function gathered(pc) { // WHEP without trickle: the offer carries every candidate
    return new Promise(function (resolve) {
      if (pc.iceGatheringState === "complete") { resolve(); return; }
      var done = function () { if (pc.iceGatheringState === "complete") resolve(); };
      pc.addEventListener("icegatheringstatechange", done);
      setTimeout(resolve, GATHER_MS);
    });
  }

  function endSession(location) {
    if (!location) return;
    fetch(location, { method: "DELETE", credentials: "same-origin", headers: { "X-CSRFToken": csrf() } })
      .catch(function () {});
  }

  Player.prototype.drop = function () {
    var self = this;
    if (!this.pc) return;
    var pc = this.pc;
    this.pc = null;
    pc.close();
    endSession(this.session);
    this.session = null;
    // The next poll connects again once the stream is live.
    if (this.card.dataset.state !== "refused") this.setState("reconnecting");
  };

  Player.prototype.onFrame = function () {
    var video = this.video, width = video.videoWidth, height = video.videoHeight;
    if (!width || !height) return;
    var rows = 2 * CELL_HEIGHT;
    if (this.canvas.width !== width) { this.canvas.width = width; this.canvas.height = rows; }
    this.context.drawImage(video, 0, 0, width, rows, 0, 0, width, rows);
    var captured = readStamp(this.context.getImageData(0, 0, width, rows).data, width);
    this.show("resolution", width + " × " + height);
    if (captured === null) return;
    this.frames++;
    this.card.dataset.frames = String(this.frames);
    this.card.dataset.captured = String(captured);
    this.delays.push(Date.now() + this.clockOffset - captured);
    if (this.delays.length > DELAYS_KEPT) this.delays.shift();
    var delay = Math.max(0, Math.round(median(this.delays)));
    this.card.dataset.delayMs = String(delay);
    this.show("delay", delay + " ms");
    this.setState("playing");
    this.show("why", "");
    this.lastFrameAt = Date.now();
  };

  // Teleoperation's view (the past view page): the live video while it is fresh enough,
  // else the past view, and the operator told which and how old the live picture is.
  var STALE_MS = 1000;
  Player.prototype.chooseView = function () {
    var mode = this.card.querySelector('[data-video="mode"]');
    if (!mode) return;
    var delay = Number(this.card.dataset.delayMs);
    var fresh = this.lastFrameAt && Date.now() - this.lastFrameAt < STALE_MS;
    var live = this.card.dataset.state === "playing" && fresh && delay <= this.maxDelay;
    this.card.dataset.view = live ? "live" : "past";
    this.video.hidden = !live;
    if (live) {
      mode.textContent = "Teleoperating on live video, " + delay + " ms old";
    } else if (fresh && this.card.dataset.state === "playing") {
      mode.textContent = "Live video is " + delay + " ms old (over " + this.maxDelay +
        " ms): teleoperating on the past view";
    } else {
      mode.textContent = "No live video: teleoperating on the past view";
    }
  };

  Player.prototype.watchFrames = function (pc) {
    var self = this;
    if (this.video.requestVideoFrameCallback) {
      var each = function () {
        if (self.pc !== pc) return;
        self.onFrame();
        self.video.requestVideoFrameCallback(each);
      };
      this.video.requestVideoFrameCallback(each);
    } else {
      var timer = setInterval(function () { if (self.pc !== pc) clearInterval(timer); else self.onFrame(); }, 100);
    }
    this.measureBitrate();
  };

  Player.prototype.measureBitrate = function () {
    var self = this;
    var pc = this.pc;
    if (!pc) return;
    pc.getStats().then(function (report) {
      report.forEach(function (stat) {
        if (stat.type !== "inbound-rtp" || stat.kind !== "video") return;
        if (self.lastBytes) {
          var bits = (stat.bytesReceived - self.lastBytes.bytes) * 8;
          var seconds = (stat.timestamp - self.lastBytes.at) / 1000;
          if (seconds > 0) {
            var kbps = Math.round(bits / seconds / 1000);
            self.card.dataset.bitrateKbps = String(kbps);
            self.show("bitrate", kbps + " kbit/s");
          }
        }
        self.lastBytes = { bytes: stat.bytesReceived, at: stat.timestamp };
      });
    }).catch(function () {}).then(function () {
      if (self.pc === pc) setTimeout(function () { self.measureBitrate(); }, 1000);
    });
  };

  // "Take a still": the media server's newest frame, stored geotagged by the portal.
  function stillButton(card) {
    var button = card.querySelector("[data-video-still]");
    var link = card.querySelector('[data-video="still"]');
    if (!button || !link) return;
    button.addEventListener("click", function () {
      button.disabled = true;
      fetch(button.dataset.stillsUrl, {
        method: "POST", credentials: "same-origin", headers: { "X-CSRFToken": csrf() },
      })
        .then(function (r) { return r.json().then(function (body) { return { ok: r.status === 201, body: body }; }); })
        .then(function (answer) {
          link.hidden = false;
          if (answer.ok) {
            link.href = answer.body.image;
            link.textContent = "Still taken at " + new Date(answer.body.taken_at).toLocaleTimeString();
            link.dataset.stillId = String(answer.body.id);
          } else {
            link.removeAttribute("href");
            link.textContent = answer.body.detail || "No still taken.";
          }
        })
        .catch(function () { link.hidden = false; link.textContent = "No still taken."; })
        .then(function () { button.disabled = false; });
    });
  }

  function start() {
    var cards = document.querySelectorAll("[data-live-video]");
    for (var i = 0; i < cards.length; i++) {
      var player = new Player(cards[i]);
      cards[i].skyhivePlayer = player; // a card without a data-video-url waits for watch(url)
      player.poll();
      if (cards[i].hasAttribute("data-teleop-switch")) {
        setInterval(player.chooseView.bind(player), 250);
      }
      stillButton(cards[i]);
    }
  }

  window.SkyhiveLiveVideo = { readStamp: readStamp, crc16: crc16, Player: Player };
  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
  else start();
})();
