// Keyboard shortcuts: one table, used both to handle keys and to write the help. Entries
// marked `photos` belong to the photo mode only; the 3D mode (a mesh) has the others.

export const SHORTCUTS = [
  { keys: ["Ctrl+Z"], what: "undo", run: (app) => app.undo() },
  { keys: ["Ctrl+Shift+Z", "Ctrl+Y"], what: "redo", run: (app) => app.redo() },
  { keys: ["Ctrl+S"], what: "save now (changes are also saved a moment after each edit)", run: (app) => app.save() },
  { keys: ["N", "Tab"], what: "next point to check", run: (app) => app.step(1) },
  { keys: ["Shift+N", "Shift+Tab"], what: "previous point to check", run: (app) => app.step(-1) },
  { keys: ["Enter"], what: "the selected point is right: mark it checked and go to the next", run: (app) => app.accept() },
  { keys: ["Delete", "Backspace"], what: "remove the selected point", run: (app) => app.removeSelected() },
  { photos: true, keys: ["M"], what: "mirror mode: dragging a left/right point on the front photo moves its partner to the mirror position",
    run: (app) => app.toggleMirror() },
  { photos: true, keys: ["Shift+M"], what: "put the selected point's partner at its mirror position", run: (app) => app.mirrorSelected() },
  { photos: true, keys: ["ArrowLeft", "ArrowRight", "ArrowUp", "ArrowDown"], what: "nudge the selected point by a pixel (with Shift: ten)",
    run: (app, e) => app.nudge(e.key, e.shiftKey ? 10 : 1) },
  { photos: true, keys: ["Shift+ArrowLeft", "Shift+ArrowRight", "Shift+ArrowUp", "Shift+ArrowDown"], hidden: true,
    run: (app, e) => app.nudge(e.key, 10) },
  { keys: ["F", "0"], what: "fit both photos in their views (the mesh: back to the front view)", run: (app) => app.fitViews() },
  { photos: true, keys: ["+", "="], what: "zoom in (around the selected point)", run: (app) => app.zoom(1.5) },
  { photos: true, keys: ["-"], what: "zoom out", run: (app) => app.zoom(1 / 1.5) },
  { keys: ["L"], what: "labels on or off", run: (app) => app.toggleLabels() },
  { photos: true, keys: ["G"], what: "place the missing points, and move those still guessed, by the generic head fitted to the points you placed",
    run: (app) => app.placeGuesses() },
  { photos: true, keys: ["T"], what: "turn the side photo's points round: placed again with the nose the other way (a profile read backwards)",
    run: (app) => app.turnSide() },
  { photos: true, keys: ["P"], what: "fit the head and show it in 3D", run: (app) => app.fit3d() },
  { keys: ["Escape"], what: "stop placing a point; clear the selection", run: (app) => app.cancel() },
  { keys: ["?"], what: "this help", run: (app) => app.toggleHelp() },
];

/** "Ctrl+Shift+Z" style name of a key event (Shift is part of letters and named keys only). */
export function keyName(e) {
  let key = e.key;
  const letter = key.length === 1 && /[a-z]/i.test(key);
  if (letter) key = key.toUpperCase();
  const parts = [];
  if (e.ctrlKey || e.metaKey) parts.push("Ctrl");
  if (e.altKey) parts.push("Alt");
  if (e.shiftKey && (letter || key.length > 1)) parts.push("Shift");
  parts.push(key);
  return parts.join("+");
}

const inMode = (s, mode) => !s.photos || mode === "photos";

export function bindShortcuts(app) {
  const table = new Map();
  for (const s of SHORTCUTS) if (inMode(s, app.mode)) for (const k of s.keys) table.set(k, s);
  window.addEventListener("keydown", (e) => {
    if (e.target.closest?.("input, textarea, select")) return;
    const s = table.get(keyName(e));
    if (!s) return;
    e.preventDefault();
    s.run(app, e);
  });
}

export function helpTable(mode = "photos") {
  const rows = SHORTCUTS.filter((s) => !s.hidden && inMode(s, mode)).map((s) => {
    const tr = document.createElement("tr");
    const keys = document.createElement("td");
    keys.innerHTML = s.keys.map(() => "<kbd></kbd>").join(" ");
    keys.querySelectorAll("kbd").forEach((k, i) => { k.textContent = s.keys[i]; });
    const what = document.createElement("td");
    what.textContent = s.what;
    tr.append(keys, what);
    return tr;
  });
  const table = document.createElement("table");
  table.append(...rows);
  return table;
}
