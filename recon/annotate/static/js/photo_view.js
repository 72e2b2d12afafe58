// One photo with its feature points: an SVG that zooms and pans, points coloured by group
// with their ids, dragging, and the guides the app asks for. Image pixels: x right, y down,
// the centre of the top-left pixel at (0, 0); the view maps them to the screen by
// screen = scale * pixel + (tx, ty).

import { add, mul } from "./geometry.js";

const SVG = "http://www.w3.org/2000/svg";
const MIN_ZOOM = 0.02, MAX_ZOOM = 40;

function el(name, attrs = {}, parent = null) {
  const e = document.createElementNS(SVG, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

export class PhotoView {
  /**
   * app: the App (store, catalogue, colours, and the drag/placement logic);
   * name: "front" or "side"; root: the element to fill; size: [width, height] pixels.
   */
  constructor(app, name, root, size) {
    this.app = app;
    this.name = name;
    this.root = root;
    this.width = size[0];
    this.height = size[1];
    this.scale = 1; this.tx = 0; this.ty = 0;
    this.userZoomed = false;
    this.markers = new Map();
    this.gesture = null;

    this.svg = el("svg", { class: "photo", "data-view": name });
    root.appendChild(this.svg);
    this.world = el("g", { class: "world" }, this.svg);
    this.image = el("image", { x: -0.5, y: -0.5, width: this.width, height: this.height,
                               preserveAspectRatio: "none" }, this.world);
    this.guides = el("g", { class: "guides" }, this.svg);
    this.layer = el("g", { class: "points" }, this.svg);

    this.svg.addEventListener("pointerdown", (e) => this._down(e));
    this.svg.addEventListener("pointermove", (e) => this._move(e));
    this.svg.addEventListener("pointerup", (e) => this._up(e));
    this.svg.addEventListener("pointercancel", (e) => this._up(e));
    this.svg.addEventListener("wheel", (e) => this._wheel(e), { passive: false });
    this.svg.addEventListener("dblclick", (e) => { if (!e.target.closest(".pt")) this.fit(); });
    this.svg.addEventListener("contextmenu", (e) => e.preventDefault());
    new ResizeObserver(() => { if (!this.userZoomed) this.fit(); else this.render(); }).observe(this.svg);
  }

  /** Show the photo (an object URL); resolves once it is decoded. */
  async setPhoto(url) {
    const probe = new Image();
    probe.src = url;
    await probe.decode();
    this.image.setAttribute("href", url);
  }

  // --- coordinates -------------------------------------------------------------------
  toScreen(p) { return [this.scale * p[0] + this.tx, this.scale * p[1] + this.ty]; }
  toImage(s) { return [(s[0] - this.tx) / this.scale, (s[1] - this.ty) / this.scale]; }

  _pointer(e) {
    const r = this.svg.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  clamp(p) {
    return [Math.min(Math.max(p[0], -0.5), this.width - 0.5), Math.min(Math.max(p[1], -0.5), this.height - 0.5)];
  }

  // --- zoom and pan ------------------------------------------------------------------
  fit() {
    const r = this.svg.getBoundingClientRect();
    if (!r.width || !r.height) return;
    this.scale = Math.min(r.width / this.width, r.height / this.height);
    this.tx = (r.width - this.scale * this.width) / 2 + 0.5 * this.scale;
    this.ty = (r.height - this.scale * this.height) / 2 + 0.5 * this.scale;
    this.userZoomed = false;
    this.render();
  }

  zoomAt(screen, factor) {
    const s = Math.min(Math.max(this.scale * factor, MIN_ZOOM), MAX_ZOOM);
    const k = s / this.scale;
    this.tx = screen[0] - (screen[0] - this.tx) * k;
    this.ty = screen[1] - (screen[1] - this.ty) * k;
    this.scale = s;
    this.userZoomed = true;
    this.render();
  }

  /** Zoom by `factor` around an image point (the view's centre when null). */
  zoomAround(p, factor) {
    const r = this.svg.getBoundingClientRect();
    this.zoomAt(p ? this.toScreen(p) : [r.width / 2, r.height / 2], factor);
  }

  /** Bring an image point to the middle of the view, at least `zoom` times the fit. */
  centreOn(p, zoom = 3) {
    const r = this.svg.getBoundingClientRect();
    const fitScale = Math.min(r.width / this.width, r.height / this.height);
    this.scale = Math.max(this.scale, fitScale * zoom);
    this.tx = r.width / 2 - this.scale * p[0];
    this.ty = r.height / 2 - this.scale * p[1];
    this.userZoomed = true;
    this.render();
  }

  _wheel(e) {
    e.preventDefault();
    this.zoomAt(this._pointer(e), Math.exp(-e.deltaY * 0.0015));
  }

  // --- pointer gestures: drag a point, place a point, pan ----------------------------
  _down(e) {
    const marker = e.target.closest(".pt");
    const at = this._pointer(e);
    if (e.button === 0 && marker) {
      const id = marker.dataset.id;
      const p = this.app.store.point(this.name, id);
      this.app.store.select(this.name, id);
      this.gesture = { kind: "drag", id, offset: [at[0] - this.toScreen(p)[0], at[1] - this.toScreen(p)[1]] };
      this.app.beginDrag(this.name, id);
    } else if (e.button === 0 && this.app.placing?.view === this.name) {
      this.app.place(this.clamp(this.toImage(at)));
      return;
    } else if (e.button === 0 || e.button === 1) {
      this.gesture = { kind: "pan", from: at, tx: this.tx, ty: this.ty };
      this.svg.classList.add("panning");
    } else {
      return;
    }
    this.svg.setPointerCapture(e.pointerId);
    e.preventDefault();
  }

  _move(e) {
    const g = this.gesture;
    if (!g) return;
    const at = this._pointer(e);
    if (g.kind === "drag") {
      this.app.dragTo(this.name, g.id, this.clamp(this.toImage([at[0] - g.offset[0], at[1] - g.offset[1]])));
    } else {
      this.tx = g.tx + at[0] - g.from[0];
      this.ty = g.ty + at[1] - g.from[1];
      this.userZoomed = true;
      this.render();
    }
  }

  _up(e) {
    const g = this.gesture;
    if (!g) return;
    this.gesture = null;
    this.svg.classList.remove("panning");
    if (this.svg.hasPointerCapture(e.pointerId)) this.svg.releasePointerCapture(e.pointerId);
    if (g.kind === "drag") this.app.endDrag(this.name, g.id);
  }

  // --- drawing -----------------------------------------------------------------------
  render() {
    this.world.setAttribute("transform", `matrix(${this.scale} 0 0 ${this.scale} ${this.tx} ${this.ty})`);
    const store = this.app.store;
    const points = store.views[this.name].points;
    const low = this.app.lowConfidence;
    const sel = store.selected;
    const twins = this.app.twinsOf(sel);
    for (const [id, m] of this.markers) {
      if (!(id in points)) { m.remove(); this.markers.delete(id); }
    }
    for (const [id, p] of Object.entries(points)) {
      let m = this.markers.get(id);
      if (!m) {
        const fp = this.app.catalogue[id];
        m = el("g", { class: "pt", "data-id": id, "data-view": this.name, "data-group": fp.group }, this.layer);
        m.style.setProperty("--colour", this.app.colours[fp.group]);
        el("circle", { class: "halo", r: 9 }, m);
        el("circle", { class: "dot", r: 4.5 }, m);
        const t = el("text", { class: "label", x: 7, y: -6 }, m);
        t.textContent = id;
        this.markers.set(id, m);
      }
      const s = this.toScreen(p);
      m.setAttribute("transform", `translate(${s[0].toFixed(2)} ${s[1].toFixed(2)})`);
      m.dataset.x = p[0];
      m.dataset.y = p[1];
      const c = store.confidence(this.name, id);
      m.classList.toggle("guess", c !== null && c <= 0);
      m.classList.toggle("low", c !== null && c > 0 && c < low);
      m.classList.toggle("selected", !!sel && sel.view === this.name && sel.id === id);
      m.classList.toggle("twin", !!sel && sel.view !== this.name && twins.has(id));
    }
    if (sel && sel.view === this.name && this.markers.has(sel.id)) this.layer.appendChild(this.markers.get(sel.id));
    this.svg.classList.toggle("placing", this.app.placing?.view === this.name);
    this._drawGuides();
  }

  /** Guides: lists of {kind, point, direction} in image pixels (lines drawn across the view). */
  setGuides(guides) {
    this.guideList = guides;
    this._drawGuides();
  }

  _drawGuides() {
    this.guides.replaceChildren();
    const span = 4 * (this.width + this.height);
    for (const g of this.guideList ?? []) {
      const a = this.toScreen(add(g.point, mul(g.direction, -span)));
      const b = this.toScreen(add(g.point, mul(g.direction, span)));
      el("line", { class: `guide guide-${g.kind}`, x1: a[0], y1: a[1], x2: b[0], y2: b[1] }, this.guides);
    }
  }
}
