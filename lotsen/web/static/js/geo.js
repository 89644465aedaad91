// Geographic coordinates for the page: WGS84 geodetic <-> local NED around the stack's origin,
// the same formulas as the server's lotsen.model.geodetic (geodetic -> ECEF -> local NED and back),
// so a node's lat/lon here equals the one in an exported GeoJSON to ~1e-9 degrees; and the Web
// Mercator tile maths of lotsen/web/tiles.py.
const A = 6378137.0, F = 1 / 298.257223563, E2 = F * (2 - F);
const RAD = Math.PI / 180;

function ecef(latDeg, lonDeg, h) {
  const lat = latDeg * RAD, lon = lonDeg * RAD;
  const s = Math.sin(lat), c = Math.cos(lat);
  const N = A / Math.sqrt(1 - E2 * s * s);
  return [(N + h) * c * Math.cos(lon), (N + h) * c * Math.sin(lon), (N * (1 - E2) + h) * s];
}

// lat/lon (deg), height (m) -> [north, east, down] in metres around origin {lat, lon, h}
export function geodeticToNed(lat, lon, h, o) {
  const [x, y, z] = ecef(lat, lon, h), [x0, y0, z0] = ecef(o.lat, o.lon, o.h);
  const dx = x - x0, dy = y - y0, dz = z - z0;
  const sl = Math.sin(o.lat * RAD), cl = Math.cos(o.lat * RAD), so = Math.sin(o.lon * RAD), co = Math.cos(o.lon * RAD);
  const e = -so * dx + co * dy;
  const n = -sl * co * dx - sl * so * dy + cl * dz;
  const u = cl * co * dx + cl * so * dy + sl * dz;
  return [n, e, -u];
}

// [north, east, down] around origin -> [lat, lon, h]
export function nedToGeodetic(n, e, d, o) {
  const u = -d;
  const sl = Math.sin(o.lat * RAD), cl = Math.cos(o.lat * RAD), so = Math.sin(o.lon * RAD), co = Math.cos(o.lon * RAD);
  const [x0, y0, z0] = ecef(o.lat, o.lon, o.h);
  const x = x0 - so * e - sl * co * n + cl * co * u;
  const y = y0 + co * e - sl * so * n + cl * so * u;
  const z = z0 + cl * n + sl * u;
  const lon = Math.atan2(y, x), p = Math.hypot(x, y);
  let lat = Math.atan2(z, p * (1 - E2)), h = 0;
  for (let i = 0; i < 6; i++) {   // converges to < 1e-12 rad in 3-4 steps away from the poles
    const s = Math.sin(lat), N = A / Math.sqrt(1 - E2 * s * s);
    h = p / Math.cos(lat) - N;
    lat = Math.atan2(z, p * (1 - E2 * N / (N + h)));
  }
  return [lat / RAD, lon / RAD, h];
}

// local (north, east) on the tangent plane -> [lat, lon] (as the server's GeoJSON export)
export function neToLatLon(n, e, o) { const [lat, lon] = nedToGeodetic(n, e, 0, o); return [lat, lon]; }
// [lat, lon] at the origin's height -> local [north, east] (as the server's GeoJSON import)
export function latLonToNe(lat, lon, o) { const [n, e] = geodeticToNed(lat, lon, o.h, o); return [n, e]; }

const MAX_LAT = 85.05112878;
export function lonLatToTile(lat, lon, z) {
  const l = Math.max(-MAX_LAT, Math.min(MAX_LAT, lat)) * RAD, n = 2 ** z;
  return [(lon + 180) / 360 * n, (1 - Math.asinh(Math.tan(l)) / Math.PI) / 2 * n];
}
export function tileToLonLat(x, y, z) {   // [lat, lon] of the tile's north-west corner
  const n = 2 ** z;
  return [Math.atan(Math.sinh(Math.PI * (1 - 2 * y / n))) / RAD, x / n * 360 - 180];
}
export function tilesForBox(south, west, north, east, zmin, zmax) {
  let count = 0;
  for (let z = zmin; z <= zmax; z++) {
    const [x0, y0] = lonLatToTile(north, west, z), [x1, y1] = lonLatToTile(south, east, z);
    const top = 2 ** z - 1;
    count += (Math.min(top, Math.floor(x1)) - Math.max(0, Math.floor(x0)) + 1) * (Math.min(top, Math.floor(y1)) - Math.max(0, Math.floor(y0)) + 1);
  }
  return count;
}
// ground metres per tile pixel (256 px tiles) at latitude `lat` and zoom z
export function metresPerPixel(lat, z) { return 156543.03392 * Math.cos(lat * RAD) / 2 ** z; }

export function fmtLatLon(lat, lon) {
  const f = (v, pos, neg) => `${Math.abs(v).toFixed(7)}° ${v >= 0 ? pos : neg}`;
  return `${f(lat, "N", "S")} ${f(lon, "E", "W")}`;
}
