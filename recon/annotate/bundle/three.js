// What the page's 3D views (the preview, the 3D mode) use of three.js, bundled into
// static/vendor/three.bundle.js by `npm run build` (esbuild), so that the page loads
// nothing from the network.
export {
  Box3, Color, DirectionalLight, Group, HemisphereLight, InstancedMesh, Matrix4, Mesh, MeshStandardMaterial,
  PerspectiveCamera, Raycaster, Scene, SphereGeometry, SRGBColorSpace, Vector2, Vector3, WebGLRenderer,
} from "three";
export { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
export { OrbitControls } from "three/addons/controls/OrbitControls.js";
