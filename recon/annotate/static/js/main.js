// The annotation page: two photo views, the list of points to check, the 3D preview, and
// the glue between them (dragging with guides, mirrored placement, saving, shortcuts).

import { Api } from "./api.js";
import { Checklist } from "./checklist.js";
import * as geo from "./geometry.js";
import { HeadView, webglAvailable } from "./head_view.js";
import { PhotoView } from "./photo_view.js";
import { bindShortcuts, helpTable } from "./shortcuts.js";
import { Store, placePoint, removePoint } from "./store.js";

const AUTOSAVE_MS = 1200;
const REFIT_MS = 800;
const $ = (id) => document.getElementById(id);

class App {
  constructor(api, state) {
    this.api = api;
    this.state = state;
    this.catalogue = Object.fromEntries(state.catalogue.map((fp) => [fp.id, fp]));
    this.order = Object.fromEntries(state.catalogue.map((fp, k) => [fp.id, k]));
    this.groups = Object.fromEntries(state.catalogue.map((fp) => [fp.id, fp.group]));
    this.colours = state.colours;
    this.lowConfidence = state.low_confidence;
    this.viewNames = ["front", "side"];
    this.sizes = Object.fromEntries(this.viewNames.map((v) => [v, [state.photos[v].width, state.photos[v].height]]));
    this.store = new Store(state.views);
    this.mirror = false;
    this.placing = null;
    this.drag = null;
    this.savedVersion = 0;
    this.saving = null;
    this.saveAgain = false;
    this.conflict = false;
    this.fitting = false;
    this.refitAgain = false;
    this.headView = null;

    this.views = {};
    for (const v of this.viewNames) {
      const box = $(`view-${v}`);
      box.querySelector(".view-title").textContent = `${v} · ${state.photos[v].name} (${this.sizes[v].join("×")})`;
      this.views[v] = new PhotoView(this, v, box.querySelector(".view-body"), this.sizes[v]);
    }
    this.checklist = new Checklist(this, $("checklist"));

    this.store.addEventListener("change", (e) => this._changed(e.detail));
    this.store.addEventListener("select", () => this.render());
    this._wire();
    bindShortcuts(this);
    this._showInitialisation();
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

  _showInitialisation() {
    const init = this.state.initialisation;
    const box = $("init-message");
    box.dataset.source = init.source;
    box.textContent = init.message;
    for (const v of this.viewNames) {
      const note = this.state.photos[v].note;
      if (note) box.textContent += ` ${v} photo: ${note}.`;
    }
  }

  // --- edits -------------------------------------------------------------------------
  _changed(detail) {
    this.render(detail.live);
    if (detail.live) return;
    this._showFileStatus();
    if (this.store.version !== this.savedVersion && !this.conflict) {
      clearTimeout(this.autosaveTimer);
      this.autosaveTimer = setTimeout(() => this.save(), AUTOSAVE_MS);
    }
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

  step(direction) {
    const item = this.checklist.next(direction);
    if (item) this.goTo(item.view, item.id);
  }

  accept() {
    const sel = this.store.selected;
    if (!sel) return this.step(1);
    const next = this.checklist.next(1);
    if (this.store.confidence(sel.view, sel.id) !== null) {
      this.store.commit(`check ${sel.id}`, (v) => { delete v[sel.view].confidence[sel.id]; });
    }
    if (next && !(next.view === sel.view && next.id === sel.id)) this.goTo(next.view, next.id);
  }

  removeSelected() {
    const sel = this.store.selected;
    if (!sel || !this.store.point(sel.view, sel.id)) return;
    this.store.commit(`remove ${sel.id}`, (v) => removePoint(v, sel.view, sel.id));
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

  undo() { const what = this.store.undo(); this.flash(what ? `Undone: ${what}` : "Nothing to undo."); }
  redo() { const what = this.store.redo(); this.flash(what ? `Redone: ${what}` : "Nothing to redo."); }

  toggleMirror() {
    this.mirror = !this.mirror;
    $("btn-mirror").setAttribute("aria-pressed", this.mirror);
    this.render();
  }

  toggleLabels() {
    const off = document.body.classList.toggle("no-labels");
    $("btn-labels").setAttribute("aria-pressed", !off);
  }

  fitViews() { for (const v of Object.values(this.views)) v.fit(); }

  zoom(factor) {
    const sel = this.store.selected;
    if (sel && this.store.point(sel.view, sel.id)) this.views[sel.view].zoomAround(this.store.point(sel.view, sel.id), factor);
    else for (const v of Object.values(this.views)) v.zoomAround(null, factor);
  }

  cancel() {
    this.placing = null;
    this.store.select(null);
  }

  toggleHelp() { $("help").hidden = !$("help").hidden; }

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

  // --- the file ----------------------------------------------------------------------
  async save(force = false) {
    clearTimeout(this.autosaveTimer);
    if (this.saving) { this.saveAgain = true; return this.saving; }
    const version = this.store.version;
    this._status("saving…", "busy");
    this.saving = this.api.send("PUT", "/api/fdp", { views: this.store.toJSON(), force })
      .then((r) => {
        this.savedVersion = version;
        this.conflict = false;
        this.savedAt = new Date();
        this._banner(null);
        if (r.backup) this.flash(`Saved; the file as it was before is kept in ${r.backup.split("/").pop()}.`);
      })
      .catch((e) => {
        if (e.status === 409) {
          this.conflict = true;
          this._banner(`${e.message}.`, [["Load it", () => this.load()], ["Overwrite it", () => this.save(true)]]);
        } else {
          this._banner(`Not saved: ${e.message}`);
        }
      })
      .finally(() => {
        this.saving = null;
        this._showFileStatus();
        if (this.saveAgain) {
          this.saveAgain = false;
          if (this.store.version !== this.savedVersion && !this.conflict) this.save();
        }
      });
    return this.saving;
  }

  async load() {
    try {
      const r = await this.api.get("/api/fdp");
      this.store.commit(`load ${this.state.file.name}`, (v) => { for (const name of this.viewNames) v[name] = r.views[name]; });
      clearTimeout(this.autosaveTimer);
      this.savedVersion = this.store.version;
      this.conflict = false;
      this.savedAt = new Date(r.saved_at * 1000);
      this._banner(null);
      this._showFileStatus();
      this.flash(`Loaded ${this.state.file.name} from disk (undo brings back what was here).`);
    } catch (e) { this.error(e); }
  }

  _showFileStatus() {
    const name = this.state.file.name;
    if (this.saving) return;
    if (this.conflict) return this._status(`${name}: changed on disk`, "error");
    if (this.store.version !== this.savedVersion) return this._status(`${name}: unsaved changes`, "dirty");
    if (this.savedAt) return this._status(`${name}: saved ${this.savedAt.toLocaleTimeString()}`, "ok");
    this._status(this.state.file.exists ? `${name}: as on disk` : `${name}: not saved yet`, "ok");
  }

  _status(text, kind) {
    const s = $("file-status");
    s.textContent = text;
    s.dataset.kind = kind;
  }

  _banner(text, actions = []) {
    const b = $("banner");
    b.hidden = !text;
    b.replaceChildren();
    if (!text) return;
    const span = document.createElement("span");
    span.textContent = text;
    b.appendChild(span);
    for (const [label, run] of actions) {
      const button = document.createElement("button");
      button.textContent = label;
      button.addEventListener("click", run);
      b.appendChild(button);
    }
  }

  flash(text) {
    const f = $("flash");
    f.textContent = text;
    f.classList.add("shown");
    clearTimeout(this.flashTimer);
    this.flashTimer = setTimeout(() => f.classList.remove("shown"), 3000);
  }

  error(e) { this._banner(e.fix ? `${e.message}` : e.message); }

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
        ? ` Largest height disagreements between the photos: ${worst.map(([i, d]) => `${i} ${d.toFixed(1)} mm`).join(", ")}.` : "");
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
    const on = (id, run) => $(id).addEventListener("click", run);
    on("btn-undo", () => this.undo());
    on("btn-redo", () => this.redo());
    on("btn-mirror", () => this.toggleMirror());
    on("btn-labels", () => this.toggleLabels());
    on("btn-fill", () => this.placeGuesses());
    on("btn-load", () => this.load());
    on("btn-save", () => this.save());
    on("btn-fit", () => this.fit3d());
    on("btn-help", () => this.toggleHelp());
    on("btn-close-3d", () => { $("preview3d").hidden = true; });
    $("help").appendChild(helpTable());
    $("help").addEventListener("click", () => { $("help").hidden = true; });
    window.addEventListener("beforeunload", (e) => {
      if (this.saving || this.store.version !== this.savedVersion) e.preventDefault();
    });
  }

  async loadPhotos() {
    await Promise.all(this.viewNames.map(async (v) => this.views[v].setPhoto(await this.api.objectUrl(`/api/photo/${v}`))));
  }
}

async function main() {
  const token = new URLSearchParams(location.hash.slice(1)).get("token");
  if (!token) {
    document.body.dataset.error = "token";
    $("init-message").textContent = "Open the address that recon annotate printed: it carries this session's key.";
    return;
  }
  const api = new Api(token);
  let state;
  try {
    state = await api.get("/api/state");
  } catch (e) {
    document.body.dataset.error = "state";
    $("init-message").textContent = `The annotation server did not answer: ${e.message}. Is recon annotate still running?`;
    return;
  }
  const app = new App(api, state);
  window.annotate = app; // for the browser tests and the console
  document.body.dataset.points = "shown";
  await app.loadPhotos();
  app.fitViews();
  document.body.dataset.ready = "true";
}

main();
