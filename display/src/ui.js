// The display's panels (issue 11 item 4): the legend, the details panel of the clicked track (every field of
// the frame plus its label) and the status bar (UTC clock, track count, frame rate, connection state).
import { KNOT_MPS, MODE3A_NONE, STATUS_COASTING, STATUS_CONFIRMED, STATUS_IDENTIFIED, flightLevel, mode3aText } from "./protocol.js";
import { LABEL_LIMIT, LEADER_S, RADAR_COLOUR, TRACK_CLASSES, classOf, cssColour } from "./render.js";

const $ = (id) => document.getElementById(id);

export function buildLegend() {
  const rows = TRACK_CLASSES.map(({ name, colour, hollow }) => {
    const css = cssColour(colour);
    const style = hollow ? `border: 2px solid ${css}` : `background: ${css}`;
    return `<div class="legend-row"><span class="legend-symbol" style="${style}"></span>${name}</div>`;
  });
  rows.push(`<div class="legend-row"><span class="legend-radar" style="border-bottom-color: ${RADAR_COLOUR}"></span>radar, range rings</div>`);
  rows.push(`<div class="legend-row legend-note">leader: ${LEADER_S} s ahead · dots: trail</div>`);
  rows.push(`<div class="legend-row legend-note">label: id callsign|A-code / FL speed</div>`);
  $("legend").innerHTML = `<div class="legend-title">Legend</div>${rows.join("")}`;
}

function formatUtc(epochMs, tS) {
  if (!Number.isFinite(epochMs) || !Number.isFinite(tS)) return "--:--:-- UTC";
  const iso = new Date(epochMs + tS * 1000).toISOString();
  return `${iso.slice(0, 10)} ${iso.slice(11, 19)} UTC`;
}

function fixed(value, digits) {
  return Number.isFinite(value) ? value.toFixed(digits) : "–";
}

// [field, value] rows of the details panel for the track in `slot`
export function detailRows(store, slot, epochMs) {
  const id = store.id[slot];
  const label = store.labels.get(id) || {};
  const status = store.status[slot];
  const ve = store.ve[slot];
  const vn = store.vn[slot];
  const fl = flightLevel(store.alt[slot]);
  const headingDeg = (Math.atan2(ve, vn) * 180) / Math.PI;
  const flags = [];
  if (status & STATUS_CONFIRMED) flags.push("confirmed");
  else flags.push("tentative");
  if (status & STATUS_COASTING) flags.push("coasting");
  if (status & STATUS_IDENTIFIED) flags.push("identified");
  return [
    ["track id", String(id)],
    ["callsign", label.callsign || "–"],
    ["ICAO 24-bit", label.icao24 || "–"],
    ["Mode 3/A", store.mode3a[slot] === MODE3A_NONE ? "–" : mode3aText(store.mode3a[slot])],
    ["status", flags.join(", ")],
    ["latitude", `${fixed(store.lat[slot], 5)}°`],
    ["longitude", `${fixed(store.lon[slot], 5)}°`],
    ["altitude", `${fixed(store.alt[slot], 0)} m`],
    ["flight level", fl === null ? "–" : `FL${String(fl).padStart(3, "0")}`],
    ["ground speed", `${fixed(Math.hypot(ve, vn) / KNOT_MPS, 0)} kt (${fixed(Math.hypot(ve, vn), 1)} m/s)`],
    ["track (heading)", `${fixed((headingDeg + 360) % 360, 1)}°`],
    ["v east / north", `${fixed(ve, 1)} / ${fixed(vn, 1)} m/s`],
    ["vertical rate", `${fixed(store.vu[slot], 1)} m/s (${fixed((store.vu[slot] * 60) / 0.3048, 0)} ft/min)`],
    ["first seen", formatUtc(epochMs, store.firstSeenS[slot])],
    ["trail points", String(store.trailCount[slot])],
  ];
}

export class Panels {
  constructor(onClose) {
    buildLegend();
    $("details-close").addEventListener("click", onClose);
  }

  showDetails(store, id, epochMs) {
    const panel = $("details");
    const slot = id === null ? undefined : store.slotOfId(id);
    if (slot === undefined) {
      panel.hidden = true;
      return;
    }
    const cls = TRACK_CLASSES[classOf(store.status[slot])];
    $("details-title").textContent = `Track ${id}`;
    $("details-title").style.color = cssColour(cls.colour);
    $("details-table").innerHTML = detailRows(store, slot, epochMs)
      .map(([field, value]) => `<tr><th>${field}</th><td data-field="${field}">${escapeHtml(value)}</td></tr>`)
      .join("");
    panel.dataset.trackId = String(id);
    panel.hidden = false;
  }

  hideDetails() {
    $("details").hidden = true;
  }

  updateStatus({ epochMs, tS, tracks, frameRate, renderP95, connection, labelsDrawn, tracksInView, service }) {
    $("status-clock").textContent = formatUtc(epochMs, tS);
    $("status-tracks").textContent = `${tracks} tracks`;
    $("status-rate").textContent = `${frameRate.toFixed(1)} frames/s`;
    $("status-render").textContent = Number.isFinite(renderP95) ? `render p95 ${renderP95.toFixed(1)} ms` : "render – ms";
    $("status-labels").textContent = tracksInView > LABEL_LIMIT ? `labels hidden (${tracksInView} in view > ${LABEL_LIMIT}): zoom in` : `${labelsDrawn} labels`;
    $("status-service").textContent = service || "";
    const state = $("status-connection");
    state.textContent = connection;
    state.className = `state-${connection.split(" ")[0]}`;
  }
}

function escapeHtml(text) {
  return text.replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);
}
