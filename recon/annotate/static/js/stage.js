// What the two 3D views share (the preview of the fitted head, and the 3D mode's mesh):
// three.js, bundled with the page (static/vendor/three.bundle.js) and loaded the first
// time a view opens, and a stage — a canvas with its renderer, lights, camera and orbit
// controls, drawn again whenever the controls or the element's size change.

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

export class Stage {
  /** root: the element the canvas fills. */
  constructor(root) {
    this.root = root;
    this.renderer = null;
  }

  /** Put a canvas of class className into root and set the scene up on background (0xRRGGBB). */
  _build(T, className, background) {
    const canvas = document.createElement("canvas");
    canvas.className = className;
    this.root.appendChild(canvas);
    this.canvas = canvas;
    this.renderer = new T.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.outputColorSpace = T.SRGBColorSpace;
    this.scene = new T.Scene();
    this.scene.background = new T.Color(background);
    this.scene.add(new T.HemisphereLight(0xffffff, 0x6a6a6a, 2.2));
    const key = new T.DirectionalLight(0xffffff, 1.6);
    key.position.set(0.4, 0.6, 1.0);
    this.scene.add(key);
    this.camera = new T.PerspectiveCamera(25, 1, 0.01, 20);
    this.controls = new T.OrbitControls(this.camera, canvas);
    this.controls.addEventListener("change", () => this.draw());
    new ResizeObserver(() => this._resize()).observe(this.root);
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
}
