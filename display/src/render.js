// Drawing of the tracks (issue 11 item 4): history trails, velocity leaders and symbols are written as pixels
// straight into one ImageData (hundreds of thousands of pixels cost a few ms, where 5 000 canvas paths cost
// ~25 ms in software rendering), then labels and the selection ring with the canvas API; the static layer
// (basemap, radars, range rings) lives on its own canvas and is redrawn only when the view changes.
import { BASEMAP_COLOURS, drawBasemap } from "./basemap.js";
import { KNOT_MPS, STATUS_COASTING, STATUS_CONFIRMED, STATUS_IDENTIFIED, flightLevel, mode3aText } from "./protocol.js";
import { TRAIL_POINTS } from "./tracks.js";

export const TRACK_CLASSES = [
  { key: "tentative", name: "tentative", colour: [233, 196, 106], hollow: true, size: 3 },
  { key: "track", name: "confirmed", colour: [61, 220, 132], hollow: false, size: 4 },
  { key: "identified", name: "identified (ADS-B)", colour: [76, 201, 240], hollow: false, size: 4 },
  { key: "coasting", name: "coasting (no plot)", colour: [160, 168, 176], hollow: true, size: 4 },
];
export const RADAR_COLOUR = "#f4d35e";
export const RING_COLOUR = "rgba(244, 211, 94, 0.35)";
// labels are drawn while at most this many tracks are in view (more would cover the map and cost
// ~10 us of text rasterising each); the status bar says when they are hidden
export const LABEL_LIMIT = 600;
// velocity leaders show where a track will be in this many seconds
export const LEADER_S = 60;
const FADE_LEVELS = 8;

export function classOf(status) {
  if (status & STATUS_COASTING) return 3;
  if (!(status & STATUS_CONFIRMED)) return 0;
  return status & STATUS_IDENTIFIED ? 2 : 1;
}

export function cssColour(rgb) {
  return `rgb(${rgb[0]}, ${rgb[1]}, ${rgb[2]})`;
}

// the label of a track: [line 1: id and callsign or Mode 3/A, line 2: flight level and ground speed]
export function labelLines(store, slot) {
  const id = store.id[slot];
  const label = store.labels.get(id);
  const code = mode3aText(store.mode3a[slot]);
  const name = (label && label.callsign) || (code ? `A${code}` : "");
  const fl = flightLevel(store.alt[slot]);
  const knots = Math.round(Math.hypot(store.ve[slot], store.vn[slot]) / KNOT_MPS);
  const level = fl === null ? "FL---" : `FL${String(fl).padStart(3, "0")}`;
  return [name ? `${id} ${name}` : `${id}`, `${level} ${knots}kt`];
}

export class Renderer {
  constructor(baseCanvas, overlayCanvas) {
    this.baseCanvas = baseCanvas;
    this.overlayCanvas = overlayCanvas;
    this.base = baseCanvas.getContext("2d", { alpha: false });
    // CPU-backed: the whole overlay is written with putImageData every frame anyway
    this.overlay = overlayCanvas.getContext("2d", { willReadFrequently: true });
    this.screenX = new Float32Array(0);
    this.screenY = new Float32Array(0);
    this.classes = new Uint8Array(0);
    this.drawnSlots = new Int32Array(0);
    this.labelsDrawn = 0;
    this.tracksInView = 0;
    // trail dot colours per class and age level, as little-endian RGBA u32 for the pixel buffer
    this.trailColours = TRACK_CLASSES.map(({ colour: [r, g, b] }) => {
      const levels = new Uint32Array(FADE_LEVELS);
      for (let k = 0; k < FADE_LEVELS; k++) {
        const alpha = Math.round(230 - (200 * k) / (FADE_LEVELS - 1));
        levels[k] = ((alpha << 24) | (b << 16) | (g << 8) | r) >>> 0;
      }
      return levels;
    });
    this.solidColours = TRACK_CLASSES.map(({ colour: [r, g, b] }) => ((255 << 24) | (b << 16) | (g << 8) | r) >>> 0);
  }

  resize(width, height) {
    for (const canvas of [this.baseCanvas, this.overlayCanvas]) {
      canvas.width = width;
      canvas.height = height;
    }
    this.imageData = this.overlay.createImageData(width, height);
    this.pixels = new Uint32Array(this.imageData.data.buffer);
  }

  drawStatic(view, basemap, sensors, projection) {
    const ctx = this.base;
    drawBasemap(ctx, basemap, view);
    if (!projection) return;
    ctx.font = "11px sans-serif";
    for (const sensor of sensors) {
      if (sensor.lat === null || sensor.lat === undefined || sensor.lon === null || sensor.lon === undefined) continue;
      const [mx, my] = projection.project(sensor.lat, sensor.lon);
      const sx = view.toScreenX(mx);
      const sy = view.toScreenY(my);
      const maxRange = sensor.max_range_m || 0;
      if (maxRange > 0) {
        const step = ringStep(maxRange);
        ctx.strokeStyle = RING_COLOUR;
        ctx.fillStyle = RING_COLOUR;
        ctx.lineWidth = 1;
        for (let r = step; r < maxRange + 1; r += step) {
          ctx.beginPath();
          ctx.arc(sx, sy, r * view.pixelsPerMetre, 0, 2 * Math.PI);
          ctx.stroke();
          ctx.fillText(`${Math.round(r / 1000)} km`, sx + 3, sy - r * view.pixelsPerMetre - 3);
        }
        ctx.beginPath();
        ctx.arc(sx, sy, maxRange * view.pixelsPerMetre, 0, 2 * Math.PI);
        ctx.strokeStyle = RADAR_COLOUR;
        ctx.stroke();
      }
      ctx.fillStyle = RADAR_COLOUR;
      ctx.beginPath();
      ctx.moveTo(sx, sy - 7);
      ctx.lineTo(sx + 6, sy + 5);
      ctx.lineTo(sx - 6, sy + 5);
      ctx.closePath();
      ctx.fill();
      ctx.fillText(sensor.name, sx + 8, sy + 12);
    }
    this.coastlineColour = BASEMAP_COLOURS.coastline;
  }

  // draws the tracks of `store` in `view`; returns the number drawn
  drawTracks(store, view, selectedId) {
    const n = store.count;
    if (this.screenX.length < n) {
      this.screenX = new Float32Array(2 * n);
      this.screenY = new Float32Array(2 * n);
      this.classes = new Uint8Array(2 * n);
    }
    const { width, height } = view;
    const { screenX, screenY, classes, pixels } = this;
    const active = store.active;
    const ppm = view.pixelsPerMetre;
    const offsetX = width / 2 - view.centerX * ppm;
    const offsetY = height / 2 + view.centerY * ppm;
    let inView = 0;
    for (let i = 0; i < n; i++) {
      const slot = active[i];
      const sx = offsetX + store.x[slot] * ppm;
      const sy = offsetY - store.y[slot] * ppm;
      screenX[i] = sx;
      screenY[i] = sy;
      classes[i] = classOf(store.status[slot]);
      if (sx >= 0 && sx < width && sy >= 0 && sy < height) inView++;
    }
    this.tracksInView = inView;
    this.drawnSlots = active;
    this.drawnCount = n;

    // trails: 2x2 pixel dots, fading with age
    pixels.fill(0);
    const tNow = store.tS;
    const { trailX, trailY, trailT, trailS } = store;
    const fadeScale = (FADE_LEVELS - 1) / trailS; // age <= trailS gives a level <= FADE_LEVELS - 1
    const lastX = width - 1;
    const lastY = height - 1;
    for (let i = 0; i < n; i++) {
      const slot = active[i];
      const colours = this.trailColours[classes[i]];
      const base = slot * TRAIL_POINTS;
      const count = store.trailCount[slot];
      // newest point first, walking the ring backwards from the write position
      let ring = store.trailHead[slot];
      for (let k = 0; k < count; k++) {
        ring = ring === 0 ? TRAIL_POINTS - 1 : ring - 1;
        const j = base + ring;
        const age = tNow - trailT[j];
        if (age > trailS) break;
        const px = (offsetX + trailX[j] * ppm) | 0;
        const py = (offsetY - trailY[j] * ppm) | 0;
        if (px < 0 || py < 0 || px >= lastX || py >= lastY) continue;
        const level = (age * fadeScale) | 0;
        const colour = colours[level < 0 ? 0 : level];
        const p = py * width + px;
        pixels[p] = colour;
        pixels[p + 1] = colour;
        pixels[p + width] = colour;
        pixels[p + width + 1] = colour;
      }
    }
    // velocity leaders and symbols, into the same pixel buffer
    const leaderPixels = LEADER_S * ppm;
    for (let i = 0; i < n; i++) {
      const slot = active[i];
      const cls = TRACK_CLASSES[classes[i]];
      const colour = this.solidColours[classes[i]];
      const sx = screenX[i];
      const sy = screenY[i];
      drawLine(pixels, width, height, sx, sy, sx + store.ve[slot] * leaderPixels, sy - store.vn[slot] * leaderPixels, colour);
      drawSquare(pixels, width, height, sx | 0, sy | 0, cls.size, cls.hollow, colour);
    }
    const ctx = this.overlay;
    ctx.putImageData(this.imageData, 0, 0);

    // labels, while few enough tracks are in view
    this.labelsDrawn = 0;
    if (inView <= LABEL_LIMIT) {
      ctx.font = "11px monospace";
      ctx.textBaseline = "bottom";
      for (let c = 0; c < TRACK_CLASSES.length; c++) {
        ctx.fillStyle = cssColour(TRACK_CLASSES[c].colour);
        for (let i = 0; i < n; i++) {
          if (classes[i] !== c) continue;
          const sx = screenX[i];
          const sy = screenY[i];
          if (sx < -50 || sy < -30 || sx > width || sy > height + 30) continue;
          const [line1, line2] = labelLines(store, active[i]);
          ctx.fillText(line1, sx + 8, sy - 6);
          ctx.fillText(line2, sx + 8, sy + 6);
          this.labelsDrawn++;
        }
      }
    }

    // the selected track: a white ring
    if (selectedId !== null) {
      const slot = store.slotOfId(selectedId);
      if (slot !== undefined) {
        const i = active.indexOf(slot);
        if (i >= 0) {
          ctx.beginPath();
          ctx.arc(screenX[i], screenY[i], 10, 0, 2 * Math.PI);
          ctx.strokeStyle = "#ffffff";
          ctx.lineWidth = 2;
          ctx.stroke();
          ctx.lineWidth = 1;
        }
      }
    }
    // reading one pixel back makes the canvas rasterise now, so the measured frame time includes it
    ctx.getImageData(0, 0, 1, 1);
    return n;
  }

  // the track drawn nearest to a canvas pixel, within maxPixels; its track id or null
  pick(store, px, py, maxPixels = 12) {
    let best = null;
    let bestD2 = maxPixels * maxPixels;
    for (let i = 0; i < this.drawnCount; i++) {
      const dx = this.screenX[i] - px;
      const dy = this.screenY[i] - py;
      const d2 = dx * dx + dy * dy;
      if (d2 <= bestD2) {
        bestD2 = d2;
        best = store.id[this.drawnSlots[i]];
      }
    }
    return best;
  }

  // where track `id` was drawn in the last frame: [x, y] canvas pixels or null
  screenPositionOf(store, id) {
    const slot = store.slotOfId(id);
    if (slot === undefined) return null;
    for (let i = 0; i < this.drawnCount; i++) {
      if (this.drawnSlots[i] === slot) return [this.screenX[i], this.screenY[i]];
    }
    return null;
  }
}

// a 1-pixel line from (x0, y0) to (x1, y1) (DDA; pixels outside the canvas skipped, at most 4096 steps)
function drawLine(pixels, width, height, x0, y0, x1, y1, colour) {
  const dx = x1 - x0;
  const dy = y1 - y0;
  const steps = Math.min(4096, Math.ceil(Math.max(Math.abs(dx), Math.abs(dy))));
  if (!(steps > 0)) return;
  const stepX = dx / steps;
  const stepY = dy / steps;
  let x = x0 + 0.5;
  let y = y0 + 0.5;
  for (let k = 0; k <= steps; k++, x += stepX, y += stepY) {
    const px = x | 0;
    const py = y | 0;
    if (px >= 0 && py >= 0 && px < width && py < height) pixels[py * width + px] = colour;
  }
}

// a (2 size + 1)-pixel square centred on (cx, cy): filled, or its 2-pixel-wide outline when hollow
function drawSquare(pixels, width, height, cx, cy, size, hollow, colour) {
  const x0 = Math.max(0, cx - size);
  const x1 = Math.min(width - 1, cx + size);
  const y0 = Math.max(0, cy - size);
  const y1 = Math.min(height - 1, cy + size);
  for (let py = y0; py <= y1; py++) {
    const row = py * width;
    const edgeRow = py - (cy - size) < 2 || cy + size - py < 2;
    for (let px = x0; px <= x1; px++) {
      if (hollow && !edgeRow && px - (cx - size) >= 2 && cx + size - px >= 2) {
        pixels[row + px] = 0; // the inside of a hollow symbol is cleared so trails do not fill it
        continue;
      }
      pixels[row + px] = colour;
    }
  }
}

// range-ring spacing: 1, 2 or 5 x 10^k metres, about five rings to the maximum range
function ringStep(maxRange) {
  const raw = maxRange / 5;
  const power = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * power >= raw) return m * power;
  return 10 * power;
}
