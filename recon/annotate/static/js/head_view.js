// The 3D preview: a head (GLB) with its feature points, turned with the mouse. The view
// knows nothing about photos: it shows whatever head and points it is given.

import { Stage, three } from "./stage.js";

export class HeadView extends Stage {
  /** root: the element to fill; colours: FP group → CSS colour. */
  constructor(root, colours) {
    super(root);
    this.colours = colours;
    this.ready = null;
    this.head = null;
    this.markers = null;
  }

  async _setup() {
    this._build(await three(), "head3d", 0xf4f4f4);
    this._resize();
  }

  /** Show a head: glb (ArrayBuffer) and points3d {id: [x, y, z]} in metres. */
  async show(glb, points3d, groups) {
    this.ready ??= this._setup();
    await this.ready;
    const T = await three();
    const gltf = await new Promise((resolve, reject) => new T.GLTFLoader().parse(glb, "", resolve, reject));
    const first = this.head === null;
    if (this.head) this.scene.remove(this.head);
    if (this.markers) this.scene.remove(this.markers);
    this.head = gltf.scene;
    this.scene.add(this.head);
    let meshes = 0;
    this.head.traverse((o) => { if (o.isMesh) meshes++; });
    this.root.dataset.meshes = meshes;

    const ids = Object.keys(points3d);
    const sphere = new T.SphereGeometry(0.0018, 10, 8);
    const dots = new T.InstancedMesh(sphere, new T.MeshStandardMaterial({ roughness: 0.5 }), ids.length);
    const m = new T.Matrix4();
    ids.forEach((id, k) => {
      m.makeTranslation(...points3d[id]);
      dots.setMatrixAt(k, m);
      dots.setColorAt(k, new T.Color(this.colours[groups[id]]));
    });
    this.markers = dots;
    this.scene.add(dots);

    if (first) {
      const box = new T.Box3().setFromObject(this.head);
      const centre = box.getCenter(new T.Vector3());
      const size = box.getSize(new T.Vector3()).length();
      this.camera.position.set(centre.x + 0.35 * size, centre.y + 0.1 * size, centre.z + 1.7 * size);
      this.camera.near = size / 100;
      this.camera.far = size * 20;
      this.camera.updateProjectionMatrix();
      this.controls.target.copy(centre);
      this.controls.update();
    }
    this.draw();
    return meshes;
  }
}
