// Plane geometry of the guides: the face's midline in the front photo (mirrored placement)
// and the map between heights in the two photos (the same-height line). Pure functions on
// [x, y] pixel pairs (x right, y down), so that they can be checked on their own.

export const add = (a, b) => [a[0] + b[0], a[1] + b[1]];
export const sub = (a, b) => [a[0] - b[0], a[1] - b[1]];
export const mul = (a, s) => [a[0] * s, a[1] * s];
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1];
export const norm = (a) => Math.hypot(a[0], a[1]);
export const unit = (a) => { const n = norm(a); return n > 0 ? [a[0] / n, a[1] / n] : [0, 0]; };

/** Total-least-squares line through points: {centre, direction (unit)}; null if under two. */
export function fitLine(points) {
  if (points.length < 2) return null;
  const c = mul(points.reduce(add, [0, 0]), 1 / points.length);
  let sxx = 0, sxy = 0, syy = 0;
  for (const p of points) {
    const d = sub(p, c);
    sxx += d[0] * d[0]; sxy += d[0] * d[1]; syy += d[1] * d[1];
  }
  if (sxx + syy === 0) return null;
  // Principal axis of the 2x2 scatter matrix.
  const angle = 0.5 * Math.atan2(2 * sxy, sxx - syy);
  return { centre: c, direction: [Math.cos(angle), Math.sin(angle)] };
}

/** Mirror image of p across the line {centre, direction}. */
export function reflect(p, line) {
  const d = sub(p, line.centre);
  const along = mul(line.direction, dot(d, line.direction));
  return add(line.centre, sub(mul(along, 2), d));
}

/**
 * The face's midline in the front photo: the line through the midline points and the
 * midpoints of the left/right pairs that are placed, leaving out the ids in `exclude`.
 * Falls back to the vertical through their mean (or through `fallbackX`).
 *
 * points: {id: [x, y]}; catalogue: {id: {side, mirror}}.
 */
export function midline(points, catalogue, exclude = [], fallbackX = 0) {
  const skip = new Set(exclude);
  const on = [];
  for (const [id, p] of Object.entries(points)) {
    if (skip.has(id)) continue;
    const fp = catalogue[id];
    if (fp.side === "C") on.push(p);
    else if (fp.side === "L" && fp.mirror in points && !skip.has(fp.mirror)) on.push(mul(add(p, points[fp.mirror]), 0.5));
  }
  const line = on.length >= 3 ? fitLine(on) : null;
  if (line) {
    // Point it downwards, so that reflections do not depend on the fit's sign.
    if (line.direction[1] < 0) line.direction = mul(line.direction, -1);
    return line;
  }
  const x = on.length ? on.reduce((s, p) => s + p[0], 0) / on.length : fallbackX;
  const y = on.length ? on.reduce((s, p) => s + p[1], 0) / on.length : 0;
  return { centre: [x, y], direction: [0, 1] };
}

/**
 * Heights in the front photo are measured across the eye line, as recon.shape.calibrate does
 * after removing the head's roll: {origin, across (unit, along the eye line), up (unit)}.
 */
export function frontFrame(front) {
  const l = front["3.5"], r = front["3.6"];
  if (!l || !r || norm(sub(l, r)) === 0) return { origin: [0, 0], across: [1, 0], up: [0, -1] };
  const across = unit(sub(l, r));
  return { origin: mul(add(l, r), 0.5), across, up: [across[1], -across[0]] };
}

export const frontHeight = (frame, p) => dot(sub(p, frame.origin), frame.up);
export const sideHeight = (p) => -p[1];

/**
 * The straight line taking side-photo heights to front-photo heights, fitted to the points
 * placed in both photos (a side point also counts for its mirror partner), leaving out the
 * ids in `exclude`: {a, b, frame, shared} with hFront = a * hSide + b.
 * Too few shared points: the photos are assumed to show the head at the same share of their
 * height (sizes: {front: [w, h], side: [w, h]}).
 */
export function heightMap(front, side, catalogue, sizes, exclude = []) {
  const skip = new Set(exclude);
  const frame = frontFrame(front);
  const pairs = [];
  for (const [id, p] of Object.entries(side)) {
    if (skip.has(id)) continue;
    const twin = id in front ? id : catalogue[id].mirror;
    if (twin && twin in front && !skip.has(twin)) pairs.push([sideHeight(p), frontHeight(frame, front[twin])]);
  }
  if (pairs.length >= 2) {
    const n = pairs.length;
    const mx = pairs.reduce((s, q) => s + q[0], 0) / n, my = pairs.reduce((s, q) => s + q[1], 0) / n;
    let sxx = 0, sxy = 0;
    for (const [x, y] of pairs) { sxx += (x - mx) ** 2; sxy += (x - mx) * (y - my); }
    if (sxx > 1e-9) {
      const a = sxy / sxx;
      if (a > 0) return { a, b: my - a * mx, frame, shared: n };
    }
  }
  const a = sizes.front[1] / sizes.side[1];
  // Row y in the side photo shows the height at row y * a in the front photo.
  let b = frontHeight(frame, [frame.origin[0], 0]);
  if (pairs.length === 1) b = pairs[0][1] - a * pairs[0][0];
  return { a, b, frame, shared: pairs.length };
}

/** The front-photo line of a given front height: {point, direction}. */
export function frontLevel(frame, h) {
  return { point: add(frame.origin, mul(frame.up, h)), direction: frame.across };
}

/** The side-photo line of a given side height. */
export function sideLevel(h) {
  return { point: [0, -h], direction: [1, 0] };
}
