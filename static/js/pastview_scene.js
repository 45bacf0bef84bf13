// The drone drawn over a past frame, with three.js.
//
// The canvas lies over the frame's picture. Its camera is the frame's camera: the same
// horizontal field of view, tilted down by the mount angle from the body's forward axis.
// The drone is a box with the real frame's proportions, left side red and right side
// green (navigation lights), a red/green arrow on top pointing forward, placed at its position
// and orientation relative to the frame (sent by the server).
import * as THREE from "three";

const RED = 0xff0000;
const GREEN = 0x00ff00;

// Rows map the frame's body axes (forward, right, down) to three.js camera axes
// (x right, y up, z towards the viewer) for a camera tilted down by `pitch` radians.
function bodyToCamera(pitch) {
  const s = Math.sin(pitch);
  const c = Math.cos(pitch);
  return new THREE.Matrix4().set(
    0, 1, 0, 0,
    s, 0, -c, 0,
    -c, 0, -s, 0,
    0, 0, 0, 1,
  );
}

function droneModel(box) {
  const { length, width, height } = box;
  const group = new THREE.Group();
  // Body axes: x forward, y right, z down. BoxGeometry faces: +x, -x, +y, -y, +z, -z.
  const face = (color) => new THREE.MeshBasicMaterial({ color });
  const body = new THREE.Mesh(new THREE.BoxGeometry(length, width, height), [
    face(0xd0d0d0), // front
    face(0x808080), // back
    face(GREEN), // right
    face(RED), // left
    face(0x303030), // bottom
    face(0xf0f0f0), // top
  ]);
  group.add(body);
  const top = -height / 2 - Math.max(0.002, height * 0.02);
  const L = length / 2;
  const W = width / 2;
  // The arrow on the top face points forward, its left half red and its right half
  // green (navigation-light colouring), so both show from behind and above.
  const half = (side) => [
    [0.9 * L, 0], [0.1 * L, 0], [0.1 * L, side * 0.6 * W], // head
    [0.1 * L, 0], [-0.8 * L, 0], [-0.8 * L, side * 0.25 * W], // shaft
    [0.1 * L, 0], [-0.8 * L, side * 0.25 * W], [0.1 * L, side * 0.25 * W],
  ];
  for (const [side, color] of [[-1, RED], [1, GREEN]]) {
    const vertices = new Float32Array(half(side).flatMap(([x, y]) => [x, y, top]));
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(vertices, 3));
    group.add(new THREE.Mesh(
      geometry, new THREE.MeshBasicMaterial({ color, side: THREE.DoubleSide }),
    ));
  }
  return group;
}

export class DroneScene {
  constructor(canvas, { box, camera }) {
    this.canvas = canvas;
    // preserveDrawingBuffer: screenshots and pixel checks read what was drawn.
    this.renderer = new THREE.WebGLRenderer({
      canvas, alpha: true, antialias: true, preserveDrawingBuffer: true,
    });
    this.renderer.setClearColor(0x000000, 0);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(60, 4 / 3, 0.05, 500);
    this.drone = droneModel(box);
    this.drone.matrixAutoUpdate = false;
    this.drone.visible = false;
    this.scene.add(this.drone);
    this.setCamera(camera);
    this.pose = null;
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
  }

  setCamera({ fov_deg: fovDeg, pitch_down_deg: pitchDeg }) {
    this.fov = (fovDeg * Math.PI) / 180;
    this.mount = bodyToCamera((pitchDeg * Math.PI) / 180);
    this.resize();
  }

  resize() {
    const width = this.canvas.clientWidth || 640;
    const height = this.canvas.clientHeight || 480;
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.setSize(width, height, false);
    this.camera.aspect = width / height;
    // fov_deg is horizontal (firmware/sim/camera.py); three.js wants the vertical one.
    const vertical = 2 * Math.atan(Math.tan(this.fov / 2) / this.camera.aspect);
    this.camera.fov = (vertical * 180) / Math.PI;
    this.camera.updateProjectionMatrix();
    this.draw();
  }

  // relative: {position: [forward, right, down], orientation: [qx, qy, qz, qw]} in the frame's reference.
  setPose(relative) {
    this.pose = relative;
    this.draw();
  }

  draw() {
    if (!this.renderer) return;
    if (this.pose) {
      const [x, y, z] = this.pose.position;
      const [qx, qy, qz, qw] = this.pose.orientation;
      const inFrame = new THREE.Matrix4().compose(
        new THREE.Vector3(x, y, z),
        new THREE.Quaternion(qx, qy, qz, qw).normalize(),
        new THREE.Vector3(1, 1, 1),
      );
      this.drone.matrix.multiplyMatrices(this.mount, inFrame);
      this.drone.visible = true;
    } else {
      this.drone.visible = false;
    }
    this.renderer.render(this.scene, this.camera);
  }
}
