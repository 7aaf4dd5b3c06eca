// Track store of the display (issue 11 item 4): the latest state of every track in the current frame, in
// flat typed arrays indexed by slot, and each track's history trail in a ring buffer of TRAIL_POINTS
// projected positions (client side; a frame is the full picture, so a track absent from a frame is gone).

export const TRAIL_POINTS = 64;

export class TrackStore {
  constructor(capacity = 1024) {
    this.slotOf = new Map(); // track id -> slot
    this.freeSlots = [];
    this.active = new Int32Array(0); // slots of the current frame, in frame order
    this.count = 0;
    this.trailS = 120;
    this.trailSpacingS = this.trailS / TRAIL_POINTS;
    this.labels = new Map(); // track id -> {callsign, icao24}
    this.tS = NaN;
    this.allocate(capacity);
  }

  allocate(capacity) {
    const grow = (old, Type, per = 1) => {
      const next = new Type(capacity * per);
      if (old) next.set(old);
      return next;
    };
    this.id = grow(this.id, Uint32Array);
    this.lat = grow(this.lat, Float32Array);
    this.lon = grow(this.lon, Float32Array);
    this.alt = grow(this.alt, Float32Array);
    this.ve = grow(this.ve, Float32Array);
    this.vn = grow(this.vn, Float32Array);
    this.vu = grow(this.vu, Float32Array);
    this.mode3a = grow(this.mode3a, Uint16Array);
    this.status = grow(this.status, Uint8Array);
    this.x = grow(this.x, Float64Array);
    this.y = grow(this.y, Float64Array);
    this.seenSequence = grow(this.seenSequence, Float64Array);
    this.firstSeenS = grow(this.firstSeenS, Float64Array);
    this.trailX = grow(this.trailX, Float32Array, TRAIL_POINTS);
    this.trailY = grow(this.trailY, Float32Array, TRAIL_POINTS);
    this.trailT = grow(this.trailT, Float64Array, TRAIL_POINTS);
    this.trailHead = grow(this.trailHead, Uint16Array); // index of the next write
    this.trailCount = grow(this.trailCount, Uint16Array);
    for (let s = capacity - 1; s >= (this.capacity || 0); s--) this.freeSlots.push(s);
    this.capacity = capacity;
  }

  setTrailSeconds(trailS) {
    this.trailS = trailS > 0 ? trailS : 120;
    this.trailSpacingS = this.trailS / TRAIL_POINTS;
  }

  clear() {
    this.slotOf.clear();
    this.freeSlots = [];
    for (let s = this.capacity - 1; s >= 0; s--) this.freeSlots.push(s);
    this.active = new Int32Array(0);
    this.count = 0;
  }

  // takes a decoded frame; positions are projected with `projection` into the store's x/y (metres)
  update(frame, projection, scratch) {
    const n = frame.n;
    if (this.freeSlots.length < n) this.allocate(Math.max(2 * this.capacity, this.slotOf.size + n));
    if (scratch.x.length < n) {
      scratch.x = new Float64Array(2 * n);
      scratch.y = new Float64Array(2 * n);
    }
    projection.projectMany(frame.lat, frame.lon, n, scratch.x, scratch.y);
    // the store's own update counter, not the frame's sequence (which restarts with the server)
    this.updates = (this.updates || 0) + 1;
    const sequence = this.updates;
    const tS = frame.tS;
    const active = new Int32Array(n);
    for (let i = 0; i < n; i++) {
      const id = frame.trackId[i];
      let slot = this.slotOf.get(id);
      if (slot === undefined) {
        slot = this.freeSlots.pop();
        this.slotOf.set(id, slot);
        this.id[slot] = id;
        this.trailCount[slot] = 0;
        this.trailHead[slot] = 0;
        this.firstSeenS[slot] = tS;
      }
      active[i] = slot;
      this.seenSequence[slot] = sequence;
      this.lat[slot] = frame.lat[i];
      this.lon[slot] = frame.lon[i];
      this.alt[slot] = frame.alt[i];
      this.ve[slot] = frame.ve[i];
      this.vn[slot] = frame.vn[i];
      this.vu[slot] = frame.vu[i];
      this.mode3a[slot] = frame.mode3a[i];
      this.status[slot] = frame.status[i];
      const x = scratch.x[i];
      const y = scratch.y[i];
      this.x[slot] = x;
      this.y[slot] = y;
      // one trail point per trailSpacingS of picture time (frames may come faster than that)
      const base = slot * TRAIL_POINTS;
      const count = this.trailCount[slot];
      const head = this.trailHead[slot];
      const lastT = count ? this.trailT[base + ((head + TRAIL_POINTS - 1) % TRAIL_POINTS)] : -Infinity;
      if (!(tS - lastT < this.trailSpacingS) && Number.isFinite(x)) {
        this.trailX[base + head] = x;
        this.trailY[base + head] = y;
        this.trailT[base + head] = tS;
        this.trailHead[slot] = (head + 1) % TRAIL_POINTS;
        if (count < TRAIL_POINTS) this.trailCount[slot] = count + 1;
      } else if (tS < lastT) {
        // picture time went back (a replay restarted): the old trail would be drawn ahead of the track
        this.trailCount[slot] = 0;
        this.trailHead[slot] = 0;
      }
    }
    // tracks absent from this frame are gone: free their slots
    for (let k = 0; k < this.active.length; k++) {
      const slot = this.active[k];
      if (this.seenSequence[slot] !== sequence && this.slotOf.get(this.id[slot]) === slot) {
        this.slotOf.delete(this.id[slot]);
        this.freeSlots.push(slot);
      }
    }
    this.active = active;
    this.count = n;
    this.tS = tS;
  }

  setLabels(labels) {
    for (const [key, label] of Object.entries(labels)) this.labels.set(Number(key), label || {});
  }

  slotOfId(id) {
    return this.slotOf.get(id);
  }
}
