// The WebSocket protocol of `skytrack serve` as the browser reads it (issue 11 item 4; the server side is
// skytrack.service.frames).  A binary frame is a 40-byte little-endian header followed by one column per
// field, n values each, 4-byte columns first so every column starts on a multiple of its item size: each
// column is a typed-array view on the received ArrayBuffer, nothing is copied or parsed byte by byte.

export const MAGIC = 0x31544b53; // b"SKT1" read as a little-endian u32
export const HEADER_BYTES = 40;
export const BYTES_PER_TRACK = 7 * 4 + 2 + 1;
export const MODE3A_NONE = 0xffff;
export const STATUS_CONFIRMED = 1;
export const STATUS_COASTING = 2;
export const STATUS_IDENTIFIED = 4;

// typed arrays use the platform's byte order; the wire is little-endian (every browser platform is)
const LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;

export function frameLength(n) {
  return HEADER_BYTES + BYTES_PER_TRACK * n;
}

export function decodeFrame(buffer) {
  if (!LITTLE_ENDIAN) throw new Error("this display reads frames with typed arrays and needs a little-endian platform");
  if (buffer.byteLength < HEADER_BYTES) {
    throw new Error(`frame of ${buffer.byteLength} bytes is shorter than the ${HEADER_BYTES}-byte header`);
  }
  const header = new DataView(buffer, 0, HEADER_BYTES);
  const magic = header.getUint32(0, true);
  if (magic !== MAGIC) throw new Error(`frame magic at byte 0 is 0x${magic.toString(16)}, expected "SKT1"`);
  const n = header.getUint32(4, true);
  if (buffer.byteLength !== frameLength(n)) {
    throw new Error(`frame of ${buffer.byteLength} bytes announces ${n} tracks: expected ${frameLength(n)} bytes`);
  }
  let offset = HEADER_BYTES;
  const column = (Type) => {
    const view = new Type(buffer, offset, n);
    offset += Type.BYTES_PER_ELEMENT * n;
    return view;
  };
  return {
    n,
    tS: header.getFloat64(8, true),
    lastPlotS: header.getFloat64(16, true),
    sequence: header.getUint32(24, true),
    flags: header.getUint32(28, true),
    sentUnixS: header.getFloat64(32, true),
    trackId: column(Uint32Array),
    lat: column(Float32Array),
    lon: column(Float32Array),
    alt: column(Float32Array),
    ve: column(Float32Array),
    vn: column(Float32Array),
    vu: column(Float32Array),
    mode3a: column(Uint16Array),
    status: column(Uint8Array),
  };
}

export function mode3aText(code) {
  return code === MODE3A_NONE ? "" : code.toString(8).padStart(4, "0");
}

export function flightLevel(altM) {
  return Number.isFinite(altM) ? Math.round(altM / 30.48) : null;
}

export const KNOT_MPS = 1852 / 3600;
