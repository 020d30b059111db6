// The site map: Leaflet in a local metric frame (CRS.Simple, 1 unit = 1 m, latlng = [y, x])
// for zones, corridors and readers, and one canvas over it for the tags, redrawn at most once
// per animation frame from a plain Map — tens of thousands of tags cost one pass, not one DOM
// node (or Leaflet layer) each.
"use strict";

// χ²(2) quantile for 95 %: the 95 % ellipse is √5.991 × the 1-σ ellipse.
const CHI2_2D_95 = 5.991;
const STATUS_STYLE = {
  confirmed: { fill: "#1f6feb", stroke: "#0b3d91" },
  tentative: { fill: "#7aa7f0", stroke: "#1f6feb" },
  coasting: { fill: null, stroke: "#ef6c00" },
  lost: { fill: null, stroke: "#78909c" },
};
const ZONE_STYLE = {
  hazard: { color: "#d32f2f", fillOpacity: 0.18, weight: 2 },
  restricted: { color: "#8e24aa", fillOpacity: 0.12, weight: 2 },
  "area-of-interest": { color: "#2e7d32", fillOpacity: 0.08, weight: 1.5 },
};
const TRAIL_POINTS = 300;
const DENSE_TAGS = 2000;

class SiteMap {
  constructor(element) {
    this.map = L.map(element, {
      crs: L.CRS.Simple,
      minZoom: -6,
      maxZoom: 6,
      zoomSnap: 0.25,
      attributionControl: false,
    });
    this.map.setView([0, 0], 0);
    this.floors = [];
    this.floor = null; // null: every height
    this.tags = new Map(); // tag → {x, y, z, cov, status, predicted, t}
    this.names = new Map(); // tag → trackable name
    this.trails = new Map(); // tag → [[x, y], …] (followed tag, replay)
    this.followed = null;
    this.planLayer = L.layerGroup().addTo(this.map); // floor-plan images, under everything
    this.plans = new Map(); // floor id → L.imageOverlay
    this.zoneLayer = L.layerGroup().addTo(this.map);
    this.siteLayer = L.layerGroup().addTo(this.map);
    this.canvas = document.createElement("canvas");
    this.canvas.className = "tag-canvas";
    Object.assign(this.canvas.style, { position: "absolute", left: 0, top: 0, zIndex: 450, pointerEvents: "none" });
    this.map.getContainer().appendChild(this.canvas);
    this.dirty = true;
    this.frames = 0; // frames drawn (the browser benchmark reads it)
    this.firstTagFrameMs = null; // performance.now() of the first frame that drew a tag
    this.onSelect = () => {};
    this.map.on("move zoom resize viewreset", () => this.invalidate());
    this.map.on("click", (e) => (this.drawing ? this.addVertex(e) : this.pick(e)));
    this.drawing = null; // the polygon being drawn: {vertices: [[x, y]], layer}
    window.addEventListener("resize", () => this.invalidate());
    const frame = () => {
      if (this.dirty) this.draw();
      requestAnimationFrame(frame);
    };
    requestAnimationFrame(frame);
  }

  invalidate() { this.dirty = true; }

  // [x, y] in m → Leaflet latlng
  static ll(p) { return L.latLng(p[1], p[0]); }

  // Floor-plan images: `images` maps a floor id to an object URL of its picture; each is placed
  // by its plan.bounds_m ([[x_min, y_min], [x_max, y_max]], m) and shown on its floor (with
  // every floor shown: the first floor's, in the site file's order, that has one).
  setPlans(images) {
    this.planLayer.clearLayers();
    this.plans.clear();
    for (const f of this.floors) {
      const url = images.get(f.id);
      if (!url || !f.plan) continue;
      const [[x0, y0], [x1, y1]] = f.plan.bounds_m;
      const overlay = L.imageOverlay(url, [[y0, x0], [y1, x1]], { opacity: 0.9, interactive: false });
      overlay.floorId = f.id;
      this.plans.set(f.id, overlay);
    }
    this.showPlan();
  }

  showPlan() {
    this.planLayer.clearLayers();
    const floor = this.floor || this.floors.find((f) => this.plans.has(f.id));
    const overlay = floor && this.plans.get(floor.id);
    if (overlay) overlay.addTo(this.planLayer);
  }

  setSite(site) {
    this.siteLayer.clearLayers();
    this.floors = site.floors || [];
    for (const c of site.corridors || []) {
      L.polyline(c.points_m.map(SiteMap.ll), { color: "#b0bec5", weight: 6, opacity: 0.7, interactive: false })
        .addTo(this.siteLayer);
    }
    for (const r of site.readers || []) {
      const marker = L.circleMarker(SiteMap.ll(r.position_m), {
        radius: 4, color: r.working ? "#37474f" : "#d32f2f", fillOpacity: 1, weight: 1,
      });
      marker.bindTooltip(r.id, { permanent: false, direction: "top", className: "reader-label" });
      marker.readerId = r.id;
      marker.addTo(this.siteLayer);
    }
    const b = site.bounds_m;
    if (b) {
      const pad = Math.max(2, 0.05 * Math.max(b.max[0] - b.min[0], b.max[1] - b.min[1]));
      // no zoom animation: the tag canvas is drawn from the map's settled view, and while a
      // CSS zoom animation runs (or never ends, in a headless browser) the Leaflet layers are
      // scaled by the transform but the canvas is not: tags drew ~20 m off their drifts
      this.map.fitBounds([[b.min[1] - pad, b.min[0] - pad], [b.max[1] + pad, b.max[0] + pad]], { animate: false });
    }
    this.invalidate();
  }

  // Readers' health colours: silent ones red and larger.
  setReaderHealth(rows) {
    const byId = new Map(rows.map((r) => [r.id, r]));
    this.siteLayer.eachLayer((layer) => {
      const health = layer.readerId && byId.get(layer.readerId);
      if (!health) return;
      // silent or marked broken: red and larger; never heard (no tag near it yet): grey
      const bad = health.status === "silent" || !health.working_in_site;
      const color = bad ? "#d32f2f" : health.status === "never-heard" ? "#b0bec5" : "#37474f";
      layer.setStyle({ color, radius: bad ? 6 : 4 });
      layer.setTooltipContent(`${health.id}: ${health.status}`);
    });
  }

  // Zones from /api/v1/zones.geojson; each polygon shown on its floor (or on every floor).
  setZones(collection) {
    this.zones = collection.features || [];
    this.drawZones();
  }

  drawZones() {
    this.zoneLayer.clearLayers();
    for (const f of this.zones || []) {
      if (!this.onFloor(f.properties["rtls:floor"], f.properties["rtls:z_range_m"])) continue;
      const kind = f.properties["rtls:kind"] || "area-of-interest";
      const ring = f.geometry.coordinates[0].map(SiteMap.ll);
      const polygon = L.polygon(ring, ZONE_STYLE[kind] || ZONE_STYLE["area-of-interest"]);
      polygon.bindTooltip(`${f.properties.name || f.properties.id} (${kind})`);
      polygon.zoneId = f.properties.id;
      polygon.addTo(this.zoneLayer);
    }
  }

  // Zone editor: clicks add vertices of a polygon in metres until it is saved or cancelled.
  startDrawing() {
    this.cancelDrawing();
    this.drawing = { vertices: [], layer: L.polygon([], { color: "#1f6feb", dashArray: "4 4" }).addTo(this.map) };
    this.map.getContainer().style.cursor = "crosshair";
  }

  addVertex(e) {
    this.drawing.vertices.push([e.latlng.lng, e.latlng.lat]);
    this.drawing.layer.setLatLngs(this.drawing.vertices.map(SiteMap.ll));
    this.onDrawn(this.drawing.vertices.length);
  }

  finishDrawing() {
    const vertices = this.drawing ? this.drawing.vertices : [];
    this.cancelDrawing();
    return vertices;
  }

  cancelDrawing() {
    if (this.drawing) this.drawing.layer.remove();
    this.drawing = null;
    this.map.getContainer().style.cursor = "";
  }

  // Zone editor: move the corners of an existing zone — a draggable handle on each corner;
  // `onMoved(vertices)` after every drag. The zone's drawn polygon follows the handles.
  startEditing(zoneId, onMoved) {
    this.stopEditing();
    const feature = (this.zones || []).find((f) => f.properties.id === zoneId);
    if (!feature) return false;
    const ring = feature.geometry.coordinates[0].slice(0, -1); // the closing vertex is the first
    const vertices = ring.map(([x, y]) => [x, y]);
    const outline = L.polygon(vertices.map(SiteMap.ll), { color: "#1f6feb", dashArray: "4 4", fillOpacity: 0.05 }).addTo(this.map);
    const handles = vertices.map((v, i) => {
      const handle = L.marker(SiteMap.ll(v), {
        draggable: true,
        keyboard: false,
        icon: L.divIcon({ className: "corner-handle", iconSize: [12, 12] }),
      }).addTo(this.map);
      handle.on("drag", (e) => {
        vertices[i] = [e.latlng.lng, e.latlng.lat];
        outline.setLatLngs(vertices.map(SiteMap.ll));
      });
      handle.on("dragend", () => onMoved(vertices.map((p) => p.slice())));
      return handle;
    });
    this.editing = { zoneId, vertices, outline, handles };
    return true;
  }

  // The edited corners (m) and the editor closed; [] when nothing was being edited.
  stopEditing() {
    if (!this.editing) return [];
    const { vertices, outline, handles } = this.editing;
    outline.remove();
    handles.forEach((h) => h.remove());
    this.editing = null;
    return vertices;
  }

  // Whether something on `floorId` or spanning `zRange` shows on the selected floor.
  onFloor(floorId, zRange) {
    if (this.floor === null) return true;
    if (floorId) return floorId === this.floor.id;
    if (zRange) return zRange[0] < this.floor.z_range_m[1] && zRange[1] > this.floor.z_range_m[0];
    return true;
  }

  setFloor(floorId) {
    this.floor = this.floors.find((f) => f.id === floorId) || null;
    this.showPlan();
    this.drawZones();
    this.invalidate();
  }

  // A tag's state from an omlox Location (live) or a stored track state (replay).
  update(tag, state) {
    this.tags.set(tag, state);
    const trail = this.trails.get(tag);
    if (trail) {
      trail.push([state.x, state.y]);
      if (trail.length > TRAIL_POINTS) trail.shift();
    }
    if (tag === this.followed) this.map.panTo(SiteMap.ll([state.x, state.y]), { animate: false });
    this.dirty = true;
  }

  remove(tag) { this.tags.delete(tag); this.dirty = true; }

  clearTags() { this.tags.clear(); this.trails.clear(); this.dirty = true; }

  follow(tag) {
    this.followed = tag;
    if (tag && !this.trails.has(tag)) this.trails.set(tag, []);
    const s = tag && this.tags.get(tag);
    if (s) this.map.setView(SiteMap.ll([s.x, s.y]), Math.max(this.map.getZoom(), 2));
    this.dirty = true;
  }

  visible(s) {
    if (this.floor === null || s.z === undefined || s.z === null) return true;
    return s.z >= this.floor.z_range_m[0] && s.z < this.floor.z_range_m[1];
  }

  pick(e) {
    const click = this.map.latLngToContainerPoint(e.latlng);
    let best = null;
    let bestDistance = 10; // px
    for (const [tag, s] of this.tags) {
      if (!this.visible(s)) continue;
      const p = this.map.latLngToContainerPoint(SiteMap.ll([s.x, s.y]));
      const d = Math.hypot(p.x - click.x, p.y - click.y);
      if (d < bestDistance) { best = tag; bestDistance = d; }
    }
    if (best) this.onSelect(best);
  }

  // Tags drawn on screen on the selected floor (the page's text count reads the live set).
  visibleCount() {
    let n = 0;
    for (const s of this.tags.values()) if (this.visible(s)) n += 1;
    return n;
  }

  draw() {
    this.dirty = false;
    this.frames += 1;
    const size = this.map.getSize();
    const ratio = window.devicePixelRatio || 1;
    if (this.canvas.width !== size.x * ratio || this.canvas.height !== size.y * ratio) {
      this.canvas.width = size.x * ratio;
      this.canvas.height = size.y * ratio;
      this.canvas.style.width = `${size.x}px`;
      this.canvas.style.height = `${size.y}px`;
    }
    const ctx = this.canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.clearRect(0, 0, size.x, size.y);
    // metres → pixels at this zoom (CRS.Simple: 2^zoom px per unit)
    const pxPerM = Math.pow(2, this.map.getZoom());
    const origin = this.map.latLngToContainerPoint([0, 0]);
    const toPx = (x, y) => [origin.x + x * pxPerM, origin.y - y * pxPerM];

    for (const [tag, trail] of this.trails) {
      if (trail.length < 2) continue;
      ctx.beginPath();
      trail.forEach(([x, y], i) => { const [px, py] = toPx(x, y); if (i) ctx.lineTo(px, py); else ctx.moveTo(px, py); });
      ctx.strokeStyle = tag === this.followed ? "rgba(31,111,235,0.8)" : "rgba(96,125,139,0.6)";
      ctx.lineWidth = 2;
      ctx.stroke();
    }

    const labels = pxPerM >= 8 || this.tags.size <= 50;
    // level of detail: above DENSE_TAGS tags on screen, squares instead of circles and no
    // ellipses (software canvas: ~3 µs per tag instead of ~3 µs per path segment); the
    // followed tag keeps its ellipse
    const dense = this.tags.size > DENSE_TAGS;
    // one path per look, stroked and filled once: ten thousand tags cost a handful of canvas
    // state changes, not ten thousand
    const ellipses = new Map(); // stroke colour → Path2D
    const dots = new Map(); // "fill|stroke|width" → {path, fill, stroke, width}
    const crosses = new Path2D();
    const named = [];
    const dot = (key, fill, stroke, width) => {
      let entry = dots.get(key);
      if (!entry) { entry = { path: new Path2D(), fill, stroke, width }; dots.set(key, entry); }
      return entry.path;
    };
    for (const [tag, s] of this.tags) {
      if (!this.visible(s)) continue;
      const [px, py] = toPx(s.x, s.y);
      if (px < -50 || py < -50 || px > size.x + 50 || py > size.y + 50) continue;
      const style = STATUS_STYLE[s.status] || STATUS_STYLE.confirmed;
      // the 95 % ellipse of the x–y covariance [[a, b], [b, d]]: eigenvalues λ₁,₂ = m ± r,
      // m = (a + d)/2, r = √(((a − d)/2)² + b²); major axis at θ = ½·atan2(2b, a − d)
      if (s.cov && s.cov.length >= 4 && (!dense || tag === this.followed)) {
        const dim = s.cov.length === 9 ? 3 : 2;
        const a = s.cov[0], b = s.cov[1], d = s.cov[dim + 1];
        const m = (a + d) / 2, r = Math.sqrt(((a - d) / 2) ** 2 + b * b);
        const major = Math.sqrt(CHI2_2D_95 * Math.max(m + r, 0)) * pxPerM;
        const minor = Math.sqrt(CHI2_2D_95 * Math.max(m - r, 0)) * pxPerM;
        if (major >= 3 && Number.isFinite(major)) {
          let path = ellipses.get(style.stroke);
          if (!path) { path = new Path2D(); ellipses.set(style.stroke, path); }
          const angle = -0.5 * Math.atan2(2 * b, a - d);
          path.moveTo(px + major * Math.cos(angle), py + major * Math.sin(angle));
          path.ellipse(px, py, major, Math.max(minor, 0.5), angle, 0, 2 * Math.PI);
        }
      }
      if (s.status === "lost") {
        // last known position: a grey cross
        crosses.moveTo(px - 4, py - 4); crosses.lineTo(px + 4, py + 4);
        crosses.moveTo(px + 4, py - 4); crosses.lineTo(px - 4, py + 4);
      } else {
        const radius = tag === this.followed ? 6 : 4;
        // predicted (coasting) states are hollow orange rings
        const fill = style.fill && !s.predicted ? style.fill : null;
        const stroke = s.predicted ? "#ef6c00" : style.stroke;
        const width = s.predicted ? 2 : 1;
        const path = dot(`${fill}|${stroke}|${width}`, fill, stroke, width);
        if (dense && tag !== this.followed) {
          path.rect(px - 2, py - 2, 4, 4);
        } else {
          path.moveTo(px + radius, py);
          path.arc(px, py, radius, 0, 2 * Math.PI);
        }
      }
      if (labels || tag === this.followed) named.push([tag, px, py]);
    }
    ctx.lineWidth = 1;
    ctx.globalAlpha = 0.35;
    for (const [stroke, path] of ellipses) { ctx.strokeStyle = stroke; ctx.stroke(path); }
    ctx.globalAlpha = 1;
    for (const { path, fill, stroke, width } of dots.values()) {
      if (fill) { ctx.fillStyle = fill; ctx.fill(path); }
      ctx.strokeStyle = stroke; ctx.lineWidth = width; ctx.stroke(path);
    }
    ctx.strokeStyle = STATUS_STYLE.lost.stroke; ctx.lineWidth = 2; ctx.stroke(crosses);
    ctx.fillStyle = "#263238";
    for (const [tag, px, py] of named) ctx.fillText(this.names.get(tag) || tag, px + 6, py - 6);
    if (this.firstTagFrameMs === null && this.tags.size > 0) this.firstTagFrameMs = performance.now();
  }
}

// A tag's state from an omlox Location of `location_updates`.
function stateFromLocation(location) {
  const c = location.position.coordinates;
  const p = location.properties || {};
  return {
    x: c[0], y: c[1], z: c.length > 2 ? c[2] : null,
    cov: p["rtls:covariance_m2"], status: p["rtls:status"] || "confirmed",
    // the time is parsed when needed (reconciling with /api/v1/tags), not for every update
    predicted: !!p["rtls:predicted"], timestamp: location.timestamp,
  };
}

// A tag's state from a stored track state (history: the engine's JSON line).
function stateFromTrackLine(line) {
  return {
    x: line.x, y: line.y, z: line.z === undefined ? null : line.z, cov: line.cov,
    status: line.status || "confirmed", predicted: !!line.predicted, t: line.t,
  };
}
