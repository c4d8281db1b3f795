// The parts of three.js the HTML report uses; scripts/build_three.sh bundles them into
// meshcheck/reports/assets/three.min.js as one classic script defining window.MeshcheckThree.
export {
  Box3, BufferAttribute, BufferGeometry, Color, DirectionalLight, DoubleSide, EdgesGeometry,
  Float32BufferAttribute, Group, HemisphereLight, InstancedMesh, LineBasicMaterial, LineSegments, Matrix4,
  Mesh, MeshStandardMaterial, PerspectiveCamera, Points, PointsMaterial, Scene, Sphere, Vector3, WebGLRenderer, REVISION,
} from "three";
export { OrbitControls } from "three/addons/controls/OrbitControls.js";
