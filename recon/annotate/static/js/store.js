// The annotation being edited: points and confidences per view, the selection, and the
// history of changes (undo/redo). Views are keyed by name ("front", "side"; a mesh view
// "mesh" in the 3D mode) and hold {points: {id: [x, y]}, confidence: {id: c}}, points in
// pixels, or [x, y, z] metres on the mesh.
//
// Events: "change" (detail {label, live}) after every edit, "select" when the selection moves.

const HISTORY = 500;

const clone = (v) => JSON.parse(JSON.stringify(v));

/** Put a point where the user placed it: a hand-placed point has no confidence. */
export function placePoint(views, view, id, xy) {
  views[view].points[id] = Array.from(xy);
  delete views[view].confidence[id];
}

export function removePoint(views, view, id) {
  delete views[view].points[id];
  delete views[view].confidence[id];
}

export class Store extends EventTarget {
  constructor(views) {
    super();
    this.views = clone(views);
    for (const v of Object.values(this.views)) v.confidence ??= {};
    this.undoStack = [];
    this.redoStack = [];
    this.selected = null; // {view, id}
    this.version = 0; // counts committed changes (autosave compares it)
    this._drag = null;
  }

  point(view, id) { return this.views[view]?.points[id] ?? null; }

  confidence(view, id) {
    const c = this.views[view]?.confidence[id];
    return c === undefined ? null : c;
  }

  toJSON() { return clone(this.views); }

  _emit(detail) { this.dispatchEvent(new CustomEvent("change", { detail })); }

  _record(label, before) {
    this.undoStack.push({ label, before });
    if (this.undoStack.length > HISTORY) this.undoStack.shift();
    this.redoStack = [];
    this.version++;
    this._emit({ label, live: false });
  }

  /** Apply mutate(views) as one undoable step; false when it changed nothing. */
  commit(label, mutate) {
    const before = JSON.stringify(this.views);
    mutate(this.views);
    if (JSON.stringify(this.views) === before) return false;
    this._record(label, before);
    return true;
  }

  /** A drag: many live moves, one undoable step. */
  beginDrag() { this._drag = JSON.stringify(this.views); }

  dragMove(mutate) {
    mutate(this.views);
    this._emit({ label: "drag", live: true });
  }

  endDrag(label) {
    const before = this._drag;
    this._drag = null;
    if (before !== null && before !== JSON.stringify(this.views)) this._record(label, before);
    else this._emit({ label, live: false });
  }

  get dragging() { return this._drag !== null; }

  canUndo() { return this.undoStack.length > 0; }
  canRedo() { return this.redoStack.length > 0; }

  undo() {
    const step = this.undoStack.pop();
    if (!step) return null;
    this.redoStack.push({ label: step.label, before: JSON.stringify(this.views) });
    this.views = JSON.parse(step.before);
    this.version++;
    this._emit({ label: `undo ${step.label}`, live: false });
    return step.label;
  }

  redo() {
    const step = this.redoStack.pop();
    if (!step) return null;
    this.undoStack.push({ label: step.label, before: JSON.stringify(this.views) });
    this.views = JSON.parse(step.before);
    this.version++;
    this._emit({ label: `redo ${step.label}`, live: false });
    return step.label;
  }

  select(view, id) {
    this.selected = view && id ? { view, id } : null;
    this.dispatchEvent(new CustomEvent("select", { detail: this.selected }));
  }
}
