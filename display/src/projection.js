// Map projection of the display (issue 11 item 4): azimuthal equidistant about the radar origin, so range
// rings are true circles and azimuths from the origin are true; plus the view transform (pan and zoom)
// from projected metres to canvas pixels.

const EARTH_RADIUS_M = 6371008.8;
const DEG = Math.PI / 180;
// points farther than this angular distance from the origin are not drawn (the projection's antipode)
export const MAX_ANGLE_RAD = 0.55 * Math.PI;

export class AzimuthalEquidistant {
  constructor(latDeg, lonDeg) {
    this.lat0 = latDeg;
    this.lon0 = lonDeg;
    this.sinLat0 = Math.sin(latDeg * DEG);
    this.cosLat0 = Math.cos(latDeg * DEG);
  }

  // projects n points (typed arrays or plain arrays of degrees) into outX/outY (metres east/north of
  // the origin); points beyond MAX_ANGLE_RAD get NaN
  projectMany(lat, lon, n, outX, outY) {
    const { sinLat0, cosLat0, lon0 } = this;
    for (let i = 0; i < n; i++) {
      const phi = lat[i] * DEG;
      const dLambda = (lon[i] - lon0) * DEG;
      const sinPhi = Math.sin(phi);
      const cosPhi = Math.cos(phi);
      const cosDLambda = Math.cos(dLambda);
      const cosC = sinLat0 * sinPhi + cosLat0 * cosPhi * cosDLambda;
      const c = Math.acos(Math.max(-1, Math.min(1, cosC)));
      if (c > MAX_ANGLE_RAD || !Number.isFinite(c)) {
        outX[i] = NaN;
        outY[i] = NaN;
        continue;
      }
      const k = c < 1e-12 ? EARTH_RADIUS_M : (EARTH_RADIUS_M * c) / Math.sin(c);
      outX[i] = k * cosPhi * Math.sin(dLambda);
      outY[i] = k * (cosLat0 * sinPhi - sinLat0 * cosPhi * cosDLambda);
    }
  }

  project(latDeg, lonDeg) {
    const x = [0];
    const y = [0];
    this.projectMany([latDeg], [lonDeg], 1, x, y);
    return [x[0], y[0]];
  }
}

// canvas pixel = centre + (metres - view centre) * pixels per metre, y up on the map
export class View {
  constructor() {
    this.centerX = 0;
    this.centerY = 0;
    this.pixelsPerMetre = 1 / 1000;
    this.width = 1;
    this.height = 1;
  }

  fit(radiusM) {
    this.centerX = 0;
    this.centerY = 0;
    this.pixelsPerMetre = Math.min(this.width, this.height) / (2 * radiusM);
  }

  toScreenX(x) {
    return this.width / 2 + (x - this.centerX) * this.pixelsPerMetre;
  }

  toScreenY(y) {
    return this.height / 2 - (y - this.centerY) * this.pixelsPerMetre;
  }

  toMetres(px, py) {
    return [
      this.centerX + (px - this.width / 2) / this.pixelsPerMetre,
      this.centerY - (py - this.height / 2) / this.pixelsPerMetre,
    ];
  }

  panPixels(dx, dy) {
    this.centerX -= dx / this.pixelsPerMetre;
    this.centerY += dy / this.pixelsPerMetre;
  }

  // zooms by factor keeping the map point under (px, py) in place; the scale stays between
  // 1 pixel per 20 km (a continent) and 1 pixel per 5 m
  zoomAt(px, py, factor) {
    const [mx, my] = this.toMetres(px, py);
    this.pixelsPerMetre = Math.min(0.2, Math.max(1 / 20000, this.pixelsPerMetre * factor));
    this.centerX = mx - (px - this.width / 2) / this.pixelsPerMetre;
    this.centerY = my + (py - this.height / 2) / this.pixelsPerMetre;
  }

  // the view's extent in metres: [xmin, ymin, xmax, ymax]
  bounds() {
    const halfW = this.width / 2 / this.pixelsPerMetre;
    const halfH = this.height / 2 / this.pixelsPerMetre;
    return [this.centerX - halfW, this.centerY - halfH, this.centerX + halfW, this.centerY + halfH];
  }
}
