// The 3D mode (recon annotate MESH): one view, the mesh, with its feature points on the
// surface; the list of points to check, undo, saving and the shortcuts as in the photo mode.

import { $, Editor } from "./editor.js";
import { webglAvailable } from "./stage.js";
import { MeshView } from "./mesh_view.js";
import { bindShortcuts, helpTable } from "./shortcuts.js";
import { placePoint } from "./store.js";

export class MeshApp extends Editor {
  constructor(api, state) {
    super(api, state, ["mesh"]);
    this.mode = "mesh";
    this.inside = new Set(state.inside);
    for (const id of ["view-front", "view-side", "btn-mirror", "btn-labels", "btn-fill", "btn-fit", "btn-turn",
      "side-facing"]) $(id).hidden = true;
    const box = $("view-mesh");
    box.hidden = false;
    const m = state.mesh;
    box.querySelector(".view-title").textContent = `mesh · ${m.name} (${m.size_cm.join(" × ")} cm in the MPEG-4 frame; ` +
      "drag a point over the surface, the mouse elsewhere turns the head)";
    this.view = new MeshView(this, box.querySelector(".view-body"));
    this._wireCommon();
    $("help").appendChild(helpTable(this.mode));
    bindShortcuts(this);
    this._showInitialisation(m.notes.length ? ` ${m.notes.join("; ")}.` : "");
    this.render();
    this._showFileStatus();
  }

  async start() {
    if (!this.state.preview.three) {
      this._banner("The 3D mode needs three.js: run npm ci && npm run build.");
      return;
    }
    if (!webglAvailable()) { this._banner("The 3D mode needs WebGL, which this browser lacks."); return; }
    await this.view.show(await this.api.bytes("/api/mesh.glb"));
    this.render();
  }

  shownIn() { return this.state.shown.mesh; }

  twinsOf() { return new Set(); }

  render(live = false) {
    this.view.render();
    this._showSelection();
    if (!live) {
      this.checklist.render();
      $("btn-undo").disabled = !this.store.canUndo();
      $("btn-redo").disabled = !this.store.canRedo();
    }
  }

  _showSelection() {
    const box = $("selection");
    const sel = this.store.selected;
    if (!sel) {
      box.innerHTML = this.placing ? "" : "<p class='hint'>Click a point to select it; drag it over the surface. <kbd>?</kbd> lists the keys.</p>";
    } else {
      const fp = this.catalogue[sel.id];
      const p = this.store.point("mesh", sel.id);
      const c = this.store.confidence("mesh", sel.id);
      box.innerHTML = "<p><span class='swatch'></span><b class='id'></b>: <span class='d'></span></p><p class='where'></p>";
      box.querySelector(".swatch").style.background = this.colours[fp.group];
      box.querySelector(".id").textContent = sel.id;
      box.querySelector(".d").textContent = fp.description;
      box.querySelector(".where").textContent = p
        ? `at (${p.map((x) => (x * 1000).toFixed(1)).join(", ")}) mm · ${c === null ? "placed by hand" : c <= 0 ? "guessed from the generic head" : `confidence ${c.toFixed(2)}`}` +
          (this.inside.has(sel.id) ? " · inside the head" : "")
        : "not placed";
    }
    if (this.placing) {
      const q = document.createElement("p");
      q.className = "placing";
      q.textContent = `Click on the mesh to place ${this.placing.id} (Esc to stop).`;
      box.appendChild(q);
    }
  }

  beginDrag() { this.placing = null; this.store.beginDrag(); }

  dragTo(view, id, p) { this.store.dragMove((v) => placePoint(v, view, id, p)); }

  endDrag(view, id) { this.store.endDrag(`move ${id}`); }

  goTo(view, id) {
    this.store.select(view, id);
    this.placing = this.store.point(view, id) || this.inside.has(id) ? null : { view, id };
    this.render();
  }

  place(p) {
    const { view, id } = this.placing;
    this.placing = null;
    this.store.commit(`place ${id}`, (v) => placePoint(v, view, id, p));
    this.store.select(view, id);
  }

  fitViews() { this.view.front(); }
}
