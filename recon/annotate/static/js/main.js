// The annotation page: the photo mode's two photo views, the 3D preview, and the glue
// between them (dragging with guides, mirrored placement, shortcuts); what both modes share
// is in editor.js, the 3D mode (a head mesh) in mesh_app.js.

import { Api } from "./api.js";
import { $, Editor } from "./editor.js";
import * as geo from "./geometry.js";
import { HeadView } from "./head_view.js";
import { webglAvailable } from "./stage.js";
import { MeshApp } from "./mesh_app.js";
import { PhotoView } from "./photo_view.js";
import { bindShortcuts, helpTable } from "./shortcuts.js";
import { placePoint } from "./store.js";

const REFIT_MS = 800;

class App extends Editor {
  constructor(api, state) {
    super(api, state, ["front", "side"]);
    this.mode = "photos";
    this.sizes = Object.fromEntries(this.viewNames.map((v) => [v, [state.photos[v].width, state.photos[v].height]]));
    this.mirror = false;
    this.fitting = false;
    this.refitAgain = false;
    this.headView = null;

    this.views = {};
    for (const v of this.viewNames) {
      const box = $(`view-${v}`);
      box.querySelector(".view-title").textContent = `${v} · ${state.photos[v].name} (${this.sizes[v].join("×")})`;
      this.views[v] = new PhotoView(this, v, box.querySelector(".view-body"), this.sizes[v]);
    }
    this._wire();
    bindShortcuts(this);
    this._showInitialisation((state.initialisation.warnings ?? []).map((w) => ` Warning: ${w}.`).join(""));
    this._showFacing(state.side_facing);
    this.render();
    this._showFileStatus();
  }

  // --- what each photo can show ------------------------------------------------------
  visibleSide() {
    const labels = Object.keys(this.store.views.side.points).map((id) => this.catalogue[id].side);
    return labels.filter((s) => s === "R").length > labels.filter((s) => s === "L").length ? "R" : "L";
  }

  shownIn(view) { return view === "front" ? this.state.shown.front : this.state.shown[`side_${this.visibleSide()}`]; }

  /** Ids that stand for the same place in the other photo as the selection (same id or its mirror). */
  twinsOf(sel) {
    if (!sel) return new Set();
    const fp = this.catalogue[sel.id];
    return new Set([sel.id, fp.mirror].filter(Boolean));
  }

  // --- drawing -----------------------------------------------------------------------
  render(live = false) {
    for (const v of Object.values(this.views)) v.render();
    if (!this.drag) this._standingGuides();
    this._showSelection();
    if (!live) {
      this.checklist.render();
      $("btn-undo").disabled = !this.store.canUndo();
      $("btn-redo").disabled = !this.store.canRedo();
    }
  }

  _standingGuides() {
    const front = [];
    if (this.mirror) {
      const m = geo.midline(this.store.views.front.points, this.catalogue, [], this.sizes.front[0] / 2);
      front.push({ kind: "midline", point: m.centre, direction: m.direction });
    }
    this.views.front.setGuides(front);
    this.views.side.setGuides([]);
  }

  _showSelection() {
    const box = $("selection");
    const sel = this.store.selected;
    if (!sel) {
      box.innerHTML = this.placing ? "" : "<p class='hint'>Click a point to select it; drag to move it. <kbd>?</kbd> lists the keys.</p>";
      if (this.placing) this._placingHint(box);
      return;
    }
    const fp = this.catalogue[sel.id];
    const p = this.store.point(sel.view, sel.id);
    const c = this.store.confidence(sel.view, sel.id);
    box.innerHTML = "<p><span class='swatch'></span><b class='id'></b> on the <span class='v'></span> photo: " +
      "<span class='d'></span></p><p class='where'></p>";
    box.querySelector(".swatch").style.background = this.colours[fp.group];
    box.querySelector(".id").textContent = sel.id;
    box.querySelector(".v").textContent = sel.view;
    box.querySelector(".d").textContent = fp.description;
    box.querySelector(".where").textContent = p
      ? `at (${p[0].toFixed(1)}, ${p[1].toFixed(1)}) px · ${c === null ? "placed by hand" : c <= 0 ? "guessed from the generic head" : `confidence ${c.toFixed(2)}`}`
      : "not placed";
    if (this.placing) this._placingHint(box);
  }

  _placingHint(box) {
    const p = document.createElement("p");
    p.className = "placing";
    p.textContent = `Click on the ${this.placing.view} photo to place ${this.placing.id} (Esc to stop).`;
    box.appendChild(p);
  }

  _showInitialisation(extra = "") {
    super._showInitialisation(this.viewNames.map((v) => this.state.photos[v].note ? ` ${v} photo: ${this.state.photos[v].note}.` : "").join("") + extra);
  }

  // --- edits -------------------------------------------------------------------------
  _changed(detail) {
    super._changed(detail);
    if (detail.live) return;
    if (!$("preview3d").hidden && $("auto-refit").checked) {
      clearTimeout(this.refitTimer);
      this.refitTimer = setTimeout(() => this.fit3d(), REFIT_MS);
    }
  }

  beginDrag(view, id) {
    this.placing = null;
    const fp = this.catalogue[id];
    const exclude = [id, fp.mirror].filter(Boolean);
    const { front, side } = this.store.views;
    this.drag = {
      view, id,
      heights: geo.heightMap(front.points, side.points, this.catalogue, this.sizes, exclude),
      midline: view === "front" && this.mirror && fp.mirror
        ? geo.midline(front.points, this.catalogue, exclude, this.sizes.front[0] / 2) : null,
    };
    this.store.beginDrag();
    this._dragGuides();
  }

  dragTo(view, id, p) {
    const partner = this.catalogue[id].mirror;
    this.store.dragMove((v) => {
      placePoint(v, view, id, p);
      if (this.drag.midline) placePoint(v, "front", partner, this.views.front.clamp(geo.reflect(p, this.drag.midline)));
    });
    this._dragGuides();
  }

  endDrag(view, id) {
    this.drag = null;
    this.store.endDrag(`move ${id}`);
  }

  /** While dragging: the same-height line in both photos (and the midline in mirror mode). */
  _dragGuides() {
    const { view, id, heights, midline } = this.drag;
    const p = this.store.point(view, id);
    let hFront, hSide;
    if (view === "front") {
      hFront = geo.frontHeight(heights.frame, p);
      hSide = (hFront - heights.b) / heights.a;
    } else {
      hSide = geo.sideHeight(p);
      hFront = heights.a * hSide + heights.b;
    }
    const front = [{ kind: "height", ...geo.frontLevel(heights.frame, hFront) }];
    if (midline) front.push({ kind: "midline", point: midline.centre, direction: midline.direction });
    this.views.front.setGuides(front);
    this.views.side.setGuides([{ kind: "height", ...geo.sideLevel(hSide) }]);
  }

  goTo(view, id) {
    this.store.select(view, id);
    const p = this.store.point(view, id);
    if (p) {
      this.placing = null;
      this.views[view].centreOn(p);
    } else {
      this.placing = { view, id };
    }
    this.render();
  }

  place(p) {
    const { view, id } = this.placing;
    this.placing = null;
    this.store.commit(`place ${id}`, (v) => placePoint(v, view, id, p));
    this.store.select(view, id);
  }

  mirrorSelected() {
    const sel = this.store.selected;
    if (!sel || sel.view !== "front") return this.flash("Mirroring works on the front photo.");
    const fp = this.catalogue[sel.id];
    const p = this.store.point("front", sel.id);
    if (!fp.mirror || !p) return this.flash(`${sel.id} has no left/right partner.`);
    const line = geo.midline(this.store.views.front.points, this.catalogue, [sel.id, fp.mirror], this.sizes.front[0] / 2);
    this.store.commit(`mirror ${sel.id}`, (v) => placePoint(v, "front", fp.mirror, this.views.front.clamp(geo.reflect(p, line))));
  }

  nudge(key, d) {
    const sel = this.store.selected;
    const p = sel && this.store.point(sel.view, sel.id);
    if (!p) return;
    const delta = { ArrowLeft: [-d, 0], ArrowRight: [d, 0], ArrowUp: [0, -d], ArrowDown: [0, d] }[key];
    const q = this.views[sel.view].clamp(geo.add(p, delta));
    this.store.commit(`nudge ${sel.id}`, (v) => placePoint(v, sel.view, sel.id, q));
  }

  toggleMirror() {
    this.mirror = !this.mirror;
    $("btn-mirror").setAttribute("aria-pressed", this.mirror);
    this.render();
  }

  fitViews() { for (const v of Object.values(this.views)) v.fit(); }

  zoom(factor) {
    const sel = this.store.selected;
    if (sel && this.store.point(sel.view, sel.id)) this.views[sel.view].zoomAround(this.store.point(sel.view, sel.id), factor);
    else for (const v of Object.values(this.views)) v.zoomAround(null, factor);
  }

  /** Missing points, and those still guessed, placed by the generic head fitted to the others. */
  async placeGuesses() {
    try {
      const r = await this.api.send("POST", "/api/complete", { views: this.store.toJSON(), replace_guesses: true });
      const n = r.placed.front.length + r.placed.side.length;
      this.store.commit("place guesses", (v) => { for (const name of this.viewNames) v[name] = r.views[name]; });
      const how = this.viewNames.map((v) => `${v}: ${r.how[v]}`).join("; ");
      this.flash(n ? `Placed ${n} points from the generic head (${how}).` : "No point to place.");
    } catch (e) { this.error(e); }
  }

  // --- the side photo's facing ------------------------------------------------------
  /** Where the nose points in the side photo, as read (with its confidence) or as turned. */
  _showFacing(f) {
    const box = $("side-facing");
    const facing = f?.facing ?? (this.visibleSide() === "L" ? "left" : "right");
    let how = "from the points";
    if (f?.turned) how = "turned round by you";
    else if (f?.given) how = "given";
    else if (f && f.confidence != null) how = `read with confidence ${f.confidence.toFixed(2)}${f.unsure ? ", unsure: check it" : ""}`;
    box.textContent = `side photo: the nose points ${facing} (${how})`;
    box.dataset.facing = facing;
    box.dataset.unsure = String(Boolean(f?.unsure));
  }

  /** The side photo's points placed again for the other facing (a profile read backwards). */
  async turnSide() {
    try {
      this.flash("turning the side photo's points round…");
      const r = await this.api.send("POST", "/api/turn", { views: this.store.toJSON() });
      this.store.commit(`turn the side photo round (nose ${r.facing})`, (v) => { v.side = r.views.side; });
      this._showFacing(r.side_facing);
      this.render();
      this.flash(`The side photo's points now face ${r.facing}: ${r.how}` + (r.placed.length
        ? `; ${r.placed.length} placed from the generic head.` : ".") + " Undo (Ctrl+Z) turns them back.");
    } catch (e) { this.error(e); }
  }

  // --- the 3D preview ----------------------------------------------------------------
  async fit3d() {
    const panel = $("preview3d");
    panel.hidden = false;
    const info = $("preview-info");
    if (!this.state.preview.three) {
      info.textContent = "3D preview unavailable: three.js is not bundled (run: npm ci && npm run build).";
      return;
    }
    if (!webglAvailable()) { info.textContent = "3D preview unavailable: this browser has no WebGL."; return; }
    if (this.fitting) { this.refitAgain = true; return; }
    this.fitting = true;
    clearTimeout(this.refitTimer);
    info.textContent = "fitting the head to the points…";
    try {
      const r = await this.api.send("POST", "/api/fit", { views: this.store.toJSON() });
      const glb = await this.api.bytes(r.glb);
      this.headView ??= new HeadView($("head-view"), this.colours);
      const meshes = await this.headView.show(glb, r.points3d, this.groups);
      const worst = Object.entries(r.height_residual_mm).filter(([, d]) => Math.abs(d) >= 1)
        .sort((a, b) => Math.abs(b[1]) - Math.abs(a[1])).slice(0, 3);
      info.textContent = `Fitted in ${r.seconds.toFixed(2)} s (${meshes} parts).` + (worst.length
        ? ` Largest height disagreements between the photos: ${worst.map(([i, d]) => `${i} ${d.toFixed(1)} mm`).join(", ")}.` : "")
        + (r.warning ? ` recon build would refuse these points: ${r.warning}.` : "");
      panel.dataset.fits = String(Number(panel.dataset.fits ?? 0) + 1);
    } catch (e) {
      info.textContent = `No fit: ${e.message}`;
    } finally {
      this.fitting = false;
      if (this.refitAgain) { this.refitAgain = false; this.fit3d(); }
    }
  }

  // --- buttons -----------------------------------------------------------------------
  _wire() {
    this._wireCommon();
    const on = (id, run) => $(id).addEventListener("click", run);
    on("btn-mirror", () => this.toggleMirror());
    on("btn-fill", () => this.placeGuesses());
    on("btn-fit", () => this.fit3d());
    on("btn-turn", () => this.turnSide());
    on("btn-close-3d", () => { $("preview3d").hidden = true; });
    $("help").appendChild(helpTable(this.mode));
  }

  async start() {
    await this.loadPhotos();
    this.fitViews();
  }

  async loadPhotos() {
    await Promise.all(this.viewNames.map(async (v) => this.views[v].setPhoto(await this.api.objectUrl(`/api/photo/${v}`))));
  }
}

async function main() {
  const api = new Api();
  let state;
  try {
    state = await api.get("/api/state");
  } catch (e) {
    if (e.status === 401) {
      document.body.dataset.error = "token";
      $("init-message").textContent = "Open the address that recon annotate printed (it works once, in one browser; "
        + "this browser has not opened it).";
      return;
    }
    document.body.dataset.error = "state";
    $("init-message").textContent = `The annotation server did not answer: ${e.message}. Is recon annotate still running?`;
    return;
  }
  document.body.dataset.mode = state.mode ?? "photos";
  const app = state.mode === "mesh" ? new MeshApp(api, state) : new App(api, state);
  window.annotate = app; // for the browser tests and the console
  document.body.dataset.points = "shown";
  await app.start();
  document.body.dataset.ready = "true";
}

main();
