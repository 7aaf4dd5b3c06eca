// The air-situation display of `skytrack serve` (issue 11 item 4): connects to ws://<host>/ws, reads the
// hello, labels and status texts and the binary track frames, and draws the picture on two canvases; the
// mouse pans (drag), zooms (wheel) and selects (click) a track.  window.skytrackStats is for the tests.
import "./style.css";
import { Basemap } from "./basemap.js";
import { decodeFrame } from "./protocol.js";
import { AzimuthalEquidistant, View } from "./projection.js";
import { Renderer } from "./render.js";
import { TrackStore } from "./tracks.js";
import { Panels } from "./ui.js";

const FRAME_TIMES_KEPT = 300;
const RECONNECT_MIN_MS = 500;
const RECONNECT_MAX_MS = 5000;
const CLICK_SLOP_PX = 4;

const stats = {
  framesReceived: 0,
  framesDrawn: 0,
  lastSequence: null,
  tracks: 0,
  tracksInView: 0,
  labelsDrawn: 0,
  frameTimesMs: [],
  frameSequences: [], // the frame sequence each render drew (-1: a render of a view change only)
  connection: "connecting",
  connects: 0,
  basemapLoaded: false,
  errors: [],
};
window.skytrackStats = stats;

const store = new TrackStore();
const view = new View();
const renderer = new Renderer(document.getElementById("basemap"), document.getElementById("overlay"));
const panels = new Panels(() => select(null));
const scratch = { x: new Float64Array(0), y: new Float64Array(0) };
let projection = null;
let basemap = null;
let hello = null;
let epochMs = NaN;
let pendingFrame = null;
let staticDirty = true;
let overlayDirty = true;
let selectedId = null;
let serviceText = "";
const receiveTimes = [];

function recordError(error) {
  stats.errors.push(String(error && error.message ? error.message : error));
  if (stats.errors.length > 20) stats.errors.shift();
  console.error(error);
}

function resize() {
  const map = document.getElementById("map");
  view.width = map.clientWidth;
  view.height = map.clientHeight;
  renderer.resize(view.width, view.height);
  staticDirty = overlayDirty = true;
}

function fitCoverage() {
  const ranges = (hello ? hello.sensors : []).map((s) => s.max_range_m || 0).filter((r) => r > 0);
  view.fit(1.1 * (ranges.length ? Math.max(...ranges) : 300000));
  staticDirty = overlayDirty = true;
}

function onHello(message) {
  const origin = message.origin;
  const sameOrigin = projection && projection.lat0 === origin.lat && projection.lon0 === origin.lon;
  hello = message;
  epochMs = Date.parse(message.epoch_utc);
  store.setTrailSeconds(Number(message.trail_s));
  if (!sameOrigin) {
    projection = new AzimuthalEquidistant(origin.lat, origin.lon);
    store.clear();
    fitCoverage();
    Basemap.load(projection)
      .then((loaded) => {
        basemap = loaded;
        stats.basemapLoaded = true;
        staticDirty = true;
      })
      .catch(recordError);
  }
  staticDirty = overlayDirty = true;
}

function onText(text) {
  const message = JSON.parse(text);
  if (message.type === "hello") onHello(message);
  else if (message.type === "labels") {
    store.setLabels(message.labels || {});
    overlayDirty = true;
  } else if (message.type === "status") {
    serviceText = Object.entries(message)
      .filter(([key]) => key !== "type")
      .map(([key, value]) => `${key} ${typeof value === "number" ? Math.round(value * 10) / 10 : value}`)
      .join(" · ");
  }
}

let reconnectDelay = RECONNECT_MIN_MS;
function connect() {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
  const socket = new WebSocket(url);
  socket.binaryType = "arraybuffer";
  stats.connection = stats.connects ? "reconnecting" : "connecting";
  socket.onopen = () => {
    stats.connection = "connected";
    stats.connects++;
    reconnectDelay = RECONNECT_MIN_MS;
  };
  socket.onmessage = (event) => {
    try {
      if (typeof event.data === "string") onText(event.data);
      else {
        // frames are full pictures: when several arrive between two paints only the newest is drawn
        pendingFrame = event.data;
        stats.framesReceived++;
        receiveTimes.push(performance.now());
      }
    } catch (error) {
      recordError(error);
    }
  };
  socket.onclose = () => {
    stats.connection = "disconnected";
    setTimeout(connect, reconnectDelay);
    reconnectDelay = Math.min(RECONNECT_MAX_MS, 2 * reconnectDelay);
  };
  socket.onerror = () => socket.close();
}

function percentile(values, q) {
  if (!values.length) return NaN;
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))];
}

function paint() {
  const started = performance.now();
  let drewFrame = false;
  if (pendingFrame && projection) {
    const frame = decodeFrame(pendingFrame);
    pendingFrame = null;
    store.update(frame, projection, scratch);
    stats.lastSequence = frame.sequence;
    overlayDirty = true;
    drewFrame = true;
  }
  if (staticDirty) {
    renderer.drawStatic(view, basemap, hello ? hello.sensors : [], projection);
    staticDirty = false;
    overlayDirty = true;
  }
  if (overlayDirty) {
    stats.tracks = renderer.drawTracks(store, view, selectedId);
    stats.tracksInView = renderer.tracksInView;
    stats.labelsDrawn = renderer.labelsDrawn;
    overlayDirty = false;
    const elapsed = performance.now() - started;
    stats.frameTimesMs.push(elapsed);
    stats.frameSequences.push(drewFrame ? stats.lastSequence : -1);
    if (stats.frameTimesMs.length > FRAME_TIMES_KEPT) {
      stats.frameTimesMs.shift();
      stats.frameSequences.shift();
    }
    if (drewFrame) stats.framesDrawn++;
    if (selectedId !== null) panels.showDetails(store, selectedId, epochMs);
  }
}

function updateStatus() {
  const now = performance.now();
  while (receiveTimes.length && receiveTimes[0] < now - 2000) receiveTimes.shift();
  panels.updateStatus({
    epochMs,
    tS: store.tS,
    tracks: store.count,
    frameRate: receiveTimes.length / 2,
    renderP95: percentile(stats.frameTimesMs.slice(-60), 0.95),
    connection: stats.connection,
    labelsDrawn: stats.labelsDrawn,
    tracksInView: stats.tracksInView,
    service: serviceText,
  });
}

function loop() {
  try {
    paint();
  } catch (error) {
    recordError(error);
  }
  requestAnimationFrame(loop);
}

function select(id) {
  selectedId = id;
  if (id === null) panels.hideDetails();
  else panels.showDetails(store, id, epochMs);
  overlayDirty = true;
}

function installMouse() {
  const canvas = document.getElementById("overlay");
  let drag = null;
  const canvasPoint = (event) => {
    const rect = canvas.getBoundingClientRect();
    return [event.clientX - rect.left, event.clientY - rect.top];
  };
  canvas.addEventListener("mousedown", (event) => {
    const [x, y] = canvasPoint(event);
    drag = { x, y, startX: x, startY: y, moved: false };
  });
  window.addEventListener("mousemove", (event) => {
    if (!drag) return;
    const [x, y] = canvasPoint(event);
    if (Math.abs(x - drag.startX) + Math.abs(y - drag.startY) > CLICK_SLOP_PX) drag.moved = true;
    if (drag.moved) {
      view.panPixels(x - drag.x, y - drag.y);
      staticDirty = true;
    }
    drag.x = x;
    drag.y = y;
  });
  window.addEventListener("mouseup", () => {
    if (drag && !drag.moved) select(renderer.pick(store, drag.startX, drag.startY));
    drag = null;
  });
  canvas.addEventListener(
    "wheel",
    (event) => {
      event.preventDefault();
      const [x, y] = canvasPoint(event);
      view.zoomAt(x, y, Math.exp(-event.deltaY * 0.0015));
      staticDirty = true;
    },
    { passive: false },
  );
  document.getElementById("reset-view").addEventListener("click", fitCoverage);
  window.addEventListener("keydown", (event) => {
    if (event.key === "r" || event.key === "R") fitCoverage();
    if (event.key === "Escape") select(null);
  });
}

// for the tests: where a track was drawn (canvas pixels; the canvas starts at the page's top-left corner), the
// selection, the view and the track store
window.skytrackDisplay = {
  screenPosition: (id) => renderer.screenPositionOf(store, id),
  select,
  view,
  store,
};

window.addEventListener("resize", resize);
resize();
installMouse();
connect();
setInterval(updateStatus, 250);
requestAnimationFrame(loop);
