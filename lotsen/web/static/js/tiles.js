// Offline map tiles under the local-metre map: only tiles the boat's server has cached (its
// /api/tiles index) are requested, from the boat itself (/tiles/z/x/y.png), so nothing leaves
// the boat's network. A tile missing at the chosen zoom is drawn from a cached parent.
import { geodeticToNed, metresPerPixel, neToLatLon, lonLatToTile, tileToLonLat } from "./geo.js";

const MAX_IMAGES = 400, MAX_DRAWN = 300;

export class TileLayer {
  constructor(onLoad) {
    this.onLoad = onLoad;
    this.byZoom = new Map();      // z -> Set("x/y")
    this.zooms = [];
    this.images = new Map();      // "z/x/y" -> Image (insertion order = LRU)
    this.visible = true;
    this.attribution = "";
    this.count = 0;
  }

  setIndex(ix) {
    this.byZoom = new Map(Object.entries(ix.zooms || {}).map(([z, list]) => [Number(z), new Set(list.map(([x, y]) => `${x}/${y}`))]));
    this.zooms = [...this.byZoom.keys()].sort((a, b) => a - b);
    this.attribution = ix.attribution || "";
    this.count = ix.count || 0;
  }

  has(z, x, y) { const s = this.byZoom.get(z); return !!s && s.has(`${x}/${y}`); }

  image(z, x, y) {
    const key = `${z}/${x}/${y}`;
    let img = this.images.get(key);
    if (img) { this.images.delete(key); this.images.set(key, img); return img; }
    img = new Image();
    img.onload = () => this.onLoad();
    img.src = `/tiles/${key}.png`;
    this.images.set(key, img);
    if (this.images.size > MAX_IMAGES) this.images.delete(this.images.keys().next().value);
    return img;
  }

  // the cached zoom to draw at the map's scale (px per metre): the tile pixel closest to a screen pixel
  chooseZoom(lat, pxPerM) {
    if (!this.zooms.length) return null;
    const ideal = Math.log2(156543.03392 * Math.cos(lat * Math.PI / 180) * pxPerM);
    let best = this.zooms[0];
    for (const z of this.zooms) if (Math.abs(z - ideal - 0.3) < Math.abs(best - ideal - 0.3)) best = z;
    return best;
  }

  // draws the visible tiles; returns how many were drawn (0: the plain grid only)
  draw(g, map, origin) {
    if (!this.visible || !this.zooms.length) return 0;
    const [nMin, eMin, nMax, eMax] = map.viewBox();
    const corners = [[nMin, eMin], [nMin, eMax], [nMax, eMin], [nMax, eMax]].map(([n, e]) => neToLatLon(n, e, origin));
    const south = Math.min(...corners.map(c => c[0])), north = Math.max(...corners.map(c => c[0]));
    const west = Math.min(...corners.map(c => c[1])), east = Math.max(...corners.map(c => c[1]));
    const z = this.chooseZoom((south + north) / 2, map.scale);
    if (z === null || metresPerPixel((south + north) / 2, z) * map.scale > 16) return 0;   // far too coarse: skip
    const [x0, y0] = lonLatToTile(north, west, z), [x1, y1] = lonLatToTile(south, east, z);
    let drawn = 0;
    g.save();
    g.globalAlpha = 0.9;
    for (let x = Math.floor(x0); x <= Math.floor(x1); x++) {
      for (let y = Math.floor(y0); y <= Math.floor(y1); y++) {
        if (drawn >= MAX_DRAWN) break;
        if (this.drawTile(g, map, origin, z, x, y)) drawn++;
      }
    }
    g.restore();
    return drawn;
  }

  drawTile(g, map, origin, z, x, y) {
    // the tile at z, else the part of a cached parent that covers it
    for (let k = 0; k <= 4 && z - k >= 0; k++) {
      const zp = z - k, xp = x >> k, yp = y >> k;
      if (!this.has(zp, xp, yp)) continue;
      const img = this.image(zp, xp, yp);
      if (!img.complete || !img.naturalWidth) return false;
      const f = 2 ** k, size = img.naturalWidth / f;
      const sx = (x - xp * f) * size, sy = (y - yp * f) * size;
      const [latN, lonW] = tileToLonLat(x, y, z), [latS, lonE] = tileToLonLat(x + 1, y + 1, z);
      const [n1, e1] = geodeticToNed(latN, lonW, origin.h, origin), [n2, e2] = geodeticToNed(latS, lonE, origin.h, origin);
      const [ax, ay] = map.toScreen(n1, e1), [bx, by] = map.toScreen(n2, e2);
      g.drawImage(img, sx, sy, size, size, ax, ay, bx - ax + 0.5, by - ay + 0.5);
      return true;
    }
    return false;
  }
}
