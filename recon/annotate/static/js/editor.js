// What both annotation modes share: the store of points and its history, the list of points
// to check, saving (autosave, conflicts, backups), loading, the status line, the banner and
// the flash messages. The photo mode (main.js) and the 3D mode (mesh_app.js) extend it with
// their views; a subclass gives viewNames, shownIn(view), render(live) and goTo(view, id).

import { Checklist } from "./checklist.js";
import { Store, removePoint } from "./store.js";

const AUTOSAVE_MS = 1200;
export const $ = (id) => document.getElementById(id);

export class Editor {
  constructor(api, state, viewNames) {
    this.api = api;
    this.state = state;
    this.catalogue = Object.fromEntries(state.catalogue.map((fp) => [fp.id, fp]));
    this.order = Object.fromEntries(state.catalogue.map((fp, k) => [fp.id, k]));
    this.groups = Object.fromEntries(state.catalogue.map((fp) => [fp.id, fp.group]));
    this.colours = state.colours;
    this.lowConfidence = state.low_confidence;
    this.viewNames = viewNames;
    this.store = new Store(state.views);
    this.placing = null;
    this.drag = null;
    this.savedVersion = 0;
    this.saving = null;
    this.saveAgain = false;
    this.conflict = false;
    this.checklist = new Checklist(this, $("checklist"));
    this.store.addEventListener("change", (e) => this._changed(e.detail));
    this.store.addEventListener("select", () => this.render());
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

  undo() { const what = this.store.undo(); this.flash(what ? `Undone: ${what}` : "Nothing to undo."); }
  redo() { const what = this.store.redo(); this.flash(what ? `Redone: ${what}` : "Nothing to redo."); }

  toggleLabels() {
    const off = document.body.classList.toggle("no-labels");
    $("btn-labels").setAttribute("aria-pressed", !off);
  }

  cancel() {
    this.placing = null;
    this.store.select(null);
  }

  toggleHelp() { $("help").hidden = !$("help").hidden; }

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

  _showInitialisation(extra = "") {
    const init = this.state.initialisation;
    const box = $("init-message");
    box.dataset.source = init.source;
    box.textContent = init.message + extra;
  }

  _wireCommon() {
    const on = (id, run) => $(id).addEventListener("click", run);
    on("btn-undo", () => this.undo());
    on("btn-redo", () => this.redo());
    on("btn-labels", () => this.toggleLabels());
    on("btn-load", () => this.load());
    on("btn-save", () => this.save());
    on("btn-help", () => this.toggleHelp());
    $("help").addEventListener("click", () => { $("help").hidden = true; });
    window.addEventListener("beforeunload", (e) => {
      if (this.saving || this.store.version !== this.savedVersion) e.preventDefault();
    });
  }
}
