// The 3D view: a head (GLB) with its feature points, turned with the mouse. three.js is
// bundled with the page (static/vendor/three.bundle.js) and loaded the first time the view
// opens. The view knows nothing about photos: it shows whatever head and points it is
// given, so that a mesh annotation mode can reuse it.

let THREE = null;

export async function three() {
  THREE ??= await import("../vendor/three.bundle.js");
  return THREE;
}

export function webglAvailable() {
  try {
    const c = document.createElement("canvas");
    return !!(c.getContext("webgl2") || c.getContext("webgl"));
  } catch { return false; }
}

export class HeadView {
  /** root: the element to fill; colours: FP group → CSS colour. */
  constructor(root, colours) {
    this.root = root;
    this.colours = colours;
    this.ready = null;
    this.head = null;
    this.markers = null;
  }

  async _setup() {
    const T = await three();
    const canvas = document.createElement("canvas");
    canvas.className = "head3d";
    this.root.appendChild(canvas);
    this.renderer = new T.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.outputColorSpace = T.SRGBColorSpace;
    this.scene = new T.Scene();
    this.scene.background = new T.Color(0xf4f4f4);
    this.scene.add(new T.HemisphereLight(0xffffff, 0x6a6a6a, 2.2));
    const key = new T.DirectionalLight(0xffffff, 1.6);
    key.position.set(0.4, 0.6, 1.0);
    this.scene.add(key);
    this.camera = new T.PerspectiveCamera(25, 1, 0.01, 20);
    this.controls = new T.OrbitControls(this.camera, canvas);
    this.controls.addEventListener("change", () => this.draw());
    new ResizeObserver(() => this._resize()).observe(this.root);
    this._resize();
  }

  _resize() {
    const w = this.root.clientWidth, h = this.root.clientHeight;
    if (!w || !h || !this.renderer) return;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.draw();
  }

  draw() { if (this.renderer) this.renderer.render(this.scene, this.camera); }

  /** Show a head: glb (ArrayBuffer) and points3d {id: [x, y, z]} in metres. */
  async show(glb, points3d, groups) {
    this.ready ??= this._setup();
    await this.ready;
    const T = THREE;
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
