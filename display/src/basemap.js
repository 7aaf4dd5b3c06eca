// Offline basemap of the display (issue 11 item 4): Natural Earth 1:50m land, coastlines and country borders
// from the world-atlas npm package (TopoJSON, served by the same server as the page: no tile server, no
// internet), projected once about the radar origin and drawn on the base canvas only when the view changes.
import { feature, mesh } from "topojson-client";
import countriesUrl from "world-atlas/countries-50m.json?url";
import { MAX_ANGLE_RAD } from "./projection.js";

export const BASEMAP_URL = countriesUrl;

// a projected polyline: Float32Array of x, y pairs plus its bounding box (for culling)
function projectLine(projection, coordinates) {
  const n = coordinates.length;
  const lat = new Float64Array(n);
  const lon = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    lon[i] = coordinates[i][0];
    lat[i] = coordinates[i][1];
  }
  const x = new Float64Array(n);
  const y = new Float64Array(n);
  projection.projectMany(lat, lon, n, x, y);
  // split where a point is beyond the projection's limit (NaN): each piece is drawn on its own
  const pieces = [];
  let start = 0;
  for (let i = 0; i <= n; i++) {
    if (i === n || Number.isNaN(x[i])) {
      if (i - start >= 2) pieces.push(makePiece(x, y, start, i));
      start = i + 1;
    }
  }
  return pieces;
}

function makePiece(x, y, start, end) {
  const points = new Float32Array(2 * (end - start));
  let xmin = Infinity, ymin = Infinity, xmax = -Infinity, ymax = -Infinity;
  for (let i = start, j = 0; i < end; i++, j += 2) {
    points[j] = x[i];
    points[j + 1] = y[i];
    if (x[i] < xmin) xmin = x[i];
    if (x[i] > xmax) xmax = x[i];
    if (y[i] < ymin) ymin = y[i];
    if (y[i] > ymax) ymax = y[i];
  }
  return { points, bbox: [xmin, ymin, xmax, ymax] };
}

function linesOf(geometry) {
  if (geometry.type === "LineString") return [geometry.coordinates];
  if (geometry.type === "MultiLineString") return geometry.coordinates;
  return [];
}

function ringsOf(geometry) {
  if (geometry.type === "Polygon") return geometry.coordinates;
  if (geometry.type === "MultiPolygon") return geometry.coordinates.flat();
  return [];
}

export class Basemap {
  constructor(topology, projection) {
    const countries = topology.objects.countries;
    this.coastlines = linesOf(mesh(topology, countries, (a, b) => a === b))
      .flatMap((line) => projectLine(projection, line));
    this.borders = linesOf(mesh(topology, countries, (a, b) => a !== b))
      .flatMap((line) => projectLine(projection, line));
    // land fill: only rings entirely within the projection's limit (a cut ring would fill wrongly)
    this.land = [];
    for (const f of feature(topology, topology.objects.land).features) {
      for (const ring of ringsOf(f.geometry)) {
        const pieces = projectLine(projection, ring);
        if (pieces.length === 1 && pieces[0].points.length === 2 * ring.length) this.land.push(pieces[0]);
      }
    }
    this.maxAngleRad = MAX_ANGLE_RAD;
  }

  static async load(projection, url = BASEMAP_URL) {
    const response = await fetch(url);
    if (!response.ok) throw new Error(`basemap ${url}: HTTP ${response.status}`);
    return new Basemap(await response.json(), projection);
  }
}

function visible(bbox, bounds) {
  return !(bbox[2] < bounds[0] || bbox[0] > bounds[2] || bbox[3] < bounds[1] || bbox[1] > bounds[3]);
}

function tracePieces(ctx, pieces, view, bounds, close) {
  ctx.beginPath();
  for (const { points, bbox } of pieces) {
    if (!visible(bbox, bounds)) continue;
    ctx.moveTo(view.toScreenX(points[0]), view.toScreenY(points[1]));
    for (let j = 2; j < points.length; j += 2) ctx.lineTo(view.toScreenX(points[j]), view.toScreenY(points[j + 1]));
    if (close) ctx.closePath();
  }
}

export const BASEMAP_COLOURS = {
  sea: "#0a1622",
  land: "#172b3a",
  coastline: "#4f87a8",
  border: "#35586e",
};

export function drawBasemap(ctx, basemap, view) {
  ctx.fillStyle = BASEMAP_COLOURS.sea;
  ctx.fillRect(0, 0, view.width, view.height);
  if (!basemap) return;
  const bounds = view.bounds();
  tracePieces(ctx, basemap.land, view, bounds, true);
  ctx.fillStyle = BASEMAP_COLOURS.land;
  ctx.fill("evenodd");
  ctx.lineWidth = 1;
  ctx.setLineDash([4, 3]);
  tracePieces(ctx, basemap.borders, view, bounds, false);
  ctx.strokeStyle = BASEMAP_COLOURS.border;
  ctx.stroke();
  ctx.setLineDash([]);
  tracePieces(ctx, basemap.coastlines, view, bounds, false);
  ctx.strokeStyle = BASEMAP_COLOURS.coastline;
  ctx.lineWidth = 1.2;
  ctx.stroke();
}
