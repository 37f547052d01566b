// envcap viewer: a street's frame in the page (envcap/core/street_frame.py, StreetUniforms.to_local).
// config.streets[i].frame = {yaw_deg, origin_xz: [ox, oz], cos_sin: [c, s]} (float64 from the
// server; yaw 0 / origin (0, 0) for a street in the world frame).  World -> frame:
//   x_f = c (x - ox) + s (z - oz),  y_f = y,  z_f = -s (x - ox) + c (z - oz),
// in float64 (JavaScript numbers), like numpy's world_to_frame; shading points go to the GLSL as
// float32(frame - origin) (origin: the uniforms' km-rounded street origin, frame m).  Directions
// stay world: the runtime GLSL turns them with EnvcapStreet.frame.

// World point p [x, y, z] (m) in the street's frame (float64).
export function toFrame(street, p) {
  const [c, s] = street.frame.cos_sin, [ox, oz] = street.frame.origin_xz;
  const dx = p[0] - ox, dz = p[2] - oz;
  return [c * dx + s * dz, p[1], -s * dx + c * dz];
}

// Frame point f (m) back in the world (float64).
export function toWorld(street, f) {
  const [c, s] = street.frame.cos_sin, [ox, oz] = street.frame.origin_xz;
  return [c * f[0] - s * f[2] + ox, f[1], s * f[0] + c * f[2] + oz];
}

// World point p as the GLSL takes it: float32(frame - origin), as StreetUniforms.to_local.
export function toLocal(street, p) {
  const f = toFrame(street, p), o = street.origin;
  return [Math.fround(f[0] - o[0]), Math.fround(f[1] - o[1]), Math.fround(f[2] - o[2])];
}

// Plan distance (m) from world point p to the street's rectangle (start..end x facades, frame).
export function distanceToStreet(street, p) {
  const f = toFrame(street, p), a = f[street.along], c = f[2 - street.along];
  return Math.max(street.start - a, 0, a - street.end) + Math.max(street.planes[0] - c, 0, c - street.planes[1]);
}

// Ground height (m) under world point p: the nearest probe's (along the street) ground plane,
// ground + ground_slope * (s - s_probe), s the along coordinate in the frame.
export function groundAt(street, p) {
  const s = toFrame(street, p)[street.along];
  let best = null, bd = Infinity;
  for (const q of street.probes) {
    const sq = toFrame(street, q.position)[street.along];
    if (Math.abs(s - sq) < bd) { bd = Math.abs(s - sq); best = { q, sq }; }
  }
  return best ? best.q.ground + (best.q.ground_slope || 0) * (s - best.sq) : street.planes[2];
}
