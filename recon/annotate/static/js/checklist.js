// The points still to look at: those a photo can show but does not have, and those whose
// confidence is low (a point placed from the generic head has confidence 0), each with the
// catalogue's description. Missing points come first, then the least confident.

export function pointsToCheck(app) {
  const items = [];
  for (const view of app.viewNames) {
    const points = app.store.views[view].points;
    for (const id of app.shownIn(view)) {
      const fp = app.catalogue[id];
      const optional = view === "mesh" ? fp.front !== "Y" && fp.side_view !== "Y" && fp.side_view !== "P"
        : (view === "front" ? fp.front : fp.side_view) === "~";
      if (!(id in points)) {
        items.push({ view, id, kind: "missing", optional, confidence: -1 });
        continue;
      }
      const c = app.store.confidence(view, id);
      if (c !== null && c < app.lowConfidence) items.push({ view, id, kind: c <= 0 ? "guess" : "low", optional, confidence: c });
    }
  }
  const order = app.order;
  items.sort((a, b) => (a.kind === "missing") !== (b.kind === "missing") ? (a.kind === "missing" ? -1 : 1)
    : a.confidence - b.confidence || a.optional - b.optional || order[a.id] - order[b.id] || (a.view < b.view ? -1 : 1));
  return items;
}

export class Checklist {
  constructor(app, root) {
    this.app = app;
    this.root = root;
    this.summary = document.createElement("p");
    this.summary.className = "summary";
    this.list = document.createElement("ol");
    this.list.className = "checklist";
    root.append(this.summary, this.list);
    this.list.addEventListener("click", (e) => {
      const li = e.target.closest("li");
      if (li) app.goTo(li.dataset.view, li.dataset.id);
    });
    this.items = [];
  }

  render() {
    const app = this.app;
    this.items = pointsToCheck(app);
    const count = (view, kind) => this.items.filter((i) => i.view === view && (kind ? i.kind === kind : i.kind !== "missing")).length;
    this.summary.textContent = app.viewNames.map((v) => `${v}: ${count(v, "missing")} missing, ${count(v)} to check`).join(" · ");
    const sel = app.store.selected;
    const rows = this.items.map((item) => {
      const fp = app.catalogue[item.id];
      const li = document.createElement("li");
      li.dataset.view = item.view;
      li.dataset.id = item.id;
      li.className = `item ${item.kind}${item.optional ? " optional" : ""}`;
      if (sel && sel.view === item.view && sel.id === item.id) li.classList.add("selected");
      const what = item.kind === "missing" ? "missing" : item.kind === "guess" ? "guessed" : `confidence ${item.confidence.toFixed(2)}`;
      li.innerHTML = `<span class="swatch"></span><b class="id"></b> <span class="view-name"></span> <span class="state"></span><br><span class="description"></span>`;
      li.querySelector(".swatch").style.background = app.colours[fp.group];
      li.querySelector(".id").textContent = item.id;
      li.querySelector(".view-name").textContent = item.view;
      li.querySelector(".state").textContent = what + (item.optional ? " (estimated point)" : "");
      li.querySelector(".description").textContent = fp.description;
      return li;
    });
    this.list.replaceChildren(...rows);
  }

  /** The item after (step 1) or before (step -1) the selection, wrapping around. */
  next(step = 1) {
    if (!this.items.length) return null;
    const sel = this.app.store.selected;
    const k = sel ? this.items.findIndex((i) => i.view === sel.view && i.id === sel.id) : -1;
    if (k < 0) return step > 0 ? this.items[0] : this.items[this.items.length - 1];
    return this.items[(k + step + this.items.length) % this.items.length];
  }
}
