// The part of three.js the viewer uses, bundled by `build.sh` into `three-subset.js` as the
// global `FreeFormThree`.
export {
  BufferAttribute, BufferGeometry, DirectionalLight, DoubleSide, DynamicDrawUsage, GridHelper,
  HemisphereLight, Mesh, MeshLambertMaterial, PerspectiveCamera, PlaneGeometry, Points,
  PointsMaterial, Quaternion, Scene, Vector3, WebGLRenderer,
} from "three";
export { OrbitControls } from "three/addons/controls/OrbitControls.js";
