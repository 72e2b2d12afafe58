// The 3D mode's view: the head mesh (GLB, neutral frame), its feature points as markers that
// are dragged over the surface (each move casts a ray from the pointer onto the mesh, so a
// point is always on it), turned and zoomed with the mouse elsewhere (OrbitControls).

import { Stage, three } from "./stage.js";

export class MeshView extends Stage {
  /** app: the MeshApp (store, catalogue, colours, drag and placement); root: the element to fill. */
  constructor(app, root) {
    super(root);
    this.app = app;
    this.markers = new Map();
    this.gesture = null;
  }

  async show(glb) {
    const T = this.T = await three();
    this._build(T, "mesh3d", 0x2b2b2b);
    this.raycaster = new T.Raycaster();
    const gltf = await new Promise((resolve, reject) => new T.GLTFLoader().parse(glb, "", resolve, reject));
    this.head = gltf.scene;
    this.scene.add(this.head);
    this.surfaces = [];
    this.head.traverse((o) => { if (o.isMesh) this.surfaces.push(o); });
    this.root.dataset.meshes = this.surfaces.length;
    const box = new T.Box3().setFromObject(this.head);
    this.centre = box.getCenter(new T.Vector3());
    this.size = box.getSize(new T.Vector3()).length();
    this.sphere = new T.SphereGeometry(this.size * 0.0045, 14, 10);
    this.markerLayer = new T.Group();
    this.scene.add(this.markerLayer);
    // Before OrbitControls sees the pointer (capture on the parent): a press on a marker drags it.
    this.root.addEventListener("pointerdown", (e) => this._down(e), { capture: true });
    window.addEventListener("pointermove", (e) => this._move(e));
    window.addEventListener("pointerup", (e) => this._up(e));
    this.front();
    this._resize();
  }

  /** Back to the front view, the whole head in sight. */
  front() {
    const c = this.centre, s = this.size;
    this.camera.position.set(c.x, c.y, c.z + 2.2 * s);
    this.camera.near = s / 100;
    this.camera.far = s * 20;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(c);
    this.controls.update();
    this.draw();
  }

  // --- pointer -----------------------------------------------------------------------
  _ndc(e) {
    const r = this.canvas.getBoundingClientRect();
    return new this.T.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  }

  _cast(e, objects) {
    this.raycaster.setFromCamera(this._ndc(e), this.camera);
    return this.raycaster.intersectObjects(objects, false)[0] ?? null;
  }

  /** The surface point under a screen position (client pixels), or null. */
  surfaceAt(e) {
    const hit = this._cast(e, this.surfaces);
    return hit ? [hit.point.x, hit.point.y, hit.point.z] : null;
  }

  _down(e) {
    if (e.button !== 0 || !this.renderer) return;
    const hit = this._cast(e, [...this.markers.values()]);
    if (hit) {
      const id = hit.object.userData.id;
      this.app.store.select("mesh", id);
      if (this.app.inside.has(id)) return; // inside the head: not dragged over the surface
      this.gesture = { id };
      this.controls.enabled = false;
      this.app.beginDrag("mesh", id);
      e.stopPropagation();
      e.preventDefault();
    } else if (this.app.placing) {
      const p = this.surfaceAt(e);
      if (p) { this.app.place(p); e.stopPropagation(); }
    }
  }

  _move(e) {
    if (!this.gesture) return;
    const p = this.surfaceAt(e);
    if (p) this.app.dragTo("mesh", this.gesture.id, p);
  }

  _up() {
    if (!this.gesture) return;
    const { id } = this.gesture;
    this.gesture = null;
    this.controls.enabled = true;
    this.app.endDrag("mesh", id);
  }

  // --- markers -----------------------------------------------------------------------
  render() {
    if (!this.renderer) return;
    const T = this.T;
    const store = this.app.store;
    const points = store.views.mesh.points;
    const sel = store.selected;
    for (const [id, m] of this.markers) {
      if (!(id in points)) { this.markerLayer.remove(m); this.markers.delete(id); }
    }
    for (const [id, p] of Object.entries(points)) {
      let m = this.markers.get(id);
      if (!m) {
        const colour = new T.Color(this.app.colours[this.app.catalogue[id].group]);
        m = new T.Mesh(this.sphere, new T.MeshStandardMaterial({ color: colour, roughness: 0.4 }));
        m.userData.id = id;
        m.userData.colour = colour;
        this.markers.set(id, m);
        this.markerLayer.add(m);
      }
      m.position.set(p[0], p[1], p[2]);
      const c = store.confidence("mesh", id);
      const selected = !!sel && sel.id === id;
      m.scale.setScalar(selected ? 1.8 : 1);
      // Guesses are pale, low confidences dimmed, the selection drawn through the surface.
      m.material.color.copy(m.userData.colour);
      if (c !== null && c <= 0) m.material.color.lerp(new T.Color(0xffffff), 0.6);
      m.material.emissive = new T.Color(selected ? 0x444444 : 0x000000);
      m.material.depthTest = !selected;
      m.renderOrder = selected ? 1 : 0;
    }
    this.draw();
  }

  /** Client pixel position of a marker (for tests and the console). */
  screenOf(id) {
    const m = this.markers.get(id);
    if (!m) return null;
    const v = m.position.clone().project(this.camera);
    const r = this.canvas.getBoundingClientRect();
    return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height];
  }
}
