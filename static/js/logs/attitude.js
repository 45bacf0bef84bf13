// The 3D attitude view: a quadcopter turned by the log's Euler angles in the order
// [Procházka 2016], §4.2.1, found: yaw about the vertical first, then pitch, then roll.

import * as THREE from "../../vendor/three/three.module.min.js";
import { getJSON } from "./api.js";
import { lastIndexAtOrBefore } from "./map.js";

// Body frame and world frame are x forward/north, y right/east, z down (NED); three.js is
// x right, y up, z towards the viewer. NED vector n appears in three.js as M·n.
const M = [
  [0, 1, 0],
  [0, 0, -1],
  [-1, 0, 0],
];

/** Body-to-world rotation R = Rz(yaw)·Ry(pitch)·Rx(roll), NED, as rows. */
export function rotationNED(yaw, pitch, roll) {
  const [cy, sy] = [Math.cos(yaw), Math.sin(yaw)];
  const [cp, sp] = [Math.cos(pitch), Math.sin(pitch)];
  const [cr, sr] = [Math.cos(roll), Math.sin(roll)];
  return [
    [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
    [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
    [-sp, cp * sr, cp * cr],
  ];
}

function multiply(a, b) {
  return a.map((row) => b[0].map((_, j) => row.reduce((sum, x, k) => sum + x * b[k][j], 0)));
}

function transpose(a) {
  return a[0].map((_, j) => a.map((row) => row[j]));
}

export class AttitudeView {
  constructor(el, readout, viewer) {
    this.el = el;
    this.readout = readout;
    this.viewer = viewer;
    this.data = null;
    this.load();
  }

  async load() {
    try {
      this.data = await getJSON(`${this.viewer.api}attitude/`, { points: 4000 });
    } catch (err) {
      this.viewer.warn(`Attitude: ${err.message}`);
      return;
    }
    if (!this.data.t.length) {
      this.el.innerHTML = '<p class="lv-missing">No roll, pitch and yaw in this log.</p>';
      this.el.style.height = "auto";
      return;
    }
    try {
      this.build();
    } catch (err) {
      this.el.innerHTML = `<p class="lv-missing">The 3D view needs WebGL, which this browser does not offer (${err.message}).</p>`;
      this.el.style.height = "auto";
      this.renderer = null;
    }
    this.viewer.state.on("cursor", () => this.update());
    this.update();
  }

  build() {
    const width = this.el.clientWidth || 300;
    const height = this.el.clientHeight || 240;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, alpha: true, preserveDrawingBuffer: false });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.setSize(width, height);
    this.el.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(40, width / height, 0.1, 100);
    // From behind-right and above the start heading, looking at the drone.
    this.camera.position.set(2.6, 2.0, 3.4);
    this.camera.lookAt(0, 0, 0);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8d99ae, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 1.4);
    sun.position.set(3, 6, 2);
    this.scene.add(sun);
    const grid = new THREE.GridHelper(6, 12, 0x98a2b3, 0xd0d5dd);
    grid.position.y = -0.7;
    this.scene.add(grid);
    const north = new THREE.ArrowHelper(new THREE.Vector3(0, 0, -1), new THREE.Vector3(0, -0.69, 0), 2.6, 0xd92d20, 0.25, 0.15);
    this.scene.add(north);
    this.drone = buildDrone();
    this.scene.add(this.drone);
    new ResizeObserver(() => {
      const w = this.el.clientWidth;
      const h = this.el.clientHeight;
      if (!w || !h) return;
      this.renderer.setSize(w, h);
      this.camera.aspect = w / h;
      this.camera.updateProjectionMatrix();
      this.render();
    }).observe(this.el);
  }

  update() {
    const data = this.data;
    const i = Math.max(lastIndexAtOrBefore(data.t, this.viewer.state.cursor), 0);
    const [roll, pitch, yaw] = [data.roll[i] ?? 0, data.pitch[i] ?? 0, data.yaw[i] ?? 0];
    const deg = (r) => `${((r * 180) / Math.PI).toFixed(1)}°`;
    this.readout.textContent = `roll ${deg(roll)} · pitch ${deg(pitch)} · yaw ${deg(yaw)}`;
    this.readout.dataset.angles = JSON.stringify({ roll, pitch, yaw });
    if (!this.renderer) return;
    const r = multiply(multiply(M, rotationNED(yaw, pitch, roll)), transpose(M));
    const m = new THREE.Matrix4().set(
      r[0][0], r[0][1], r[0][2], 0,
      r[1][0], r[1][1], r[1][2], 0,
      r[2][0], r[2][1], r[2][2], 0,
      0, 0, 0, 1,
    );
    this.drone.quaternion.setFromRotationMatrix(m);
    this.render();
  }

  render() {
    if (this.renderer) this.renderer.render(this.scene, this.camera);
  }
}

/** A quadcopter in three.js axes: nose towards −z (north at yaw 0), right towards +x. */
function buildDrone() {
  const drone = new THREE.Group();
  const dark = new THREE.MeshStandardMaterial({ color: 0x344054, roughness: 0.6 });
  const body = new THREE.Mesh(new THREE.BoxGeometry(0.42, 0.14, 0.62), dark);
  drone.add(body);
  const nose = new THREE.Mesh(new THREE.ConeGeometry(0.09, 0.28, 16), new THREE.MeshStandardMaterial({ color: 0xd92d20 }));
  nose.rotation.x = -Math.PI / 2;
  nose.position.set(0, 0, -0.42);
  drone.add(nose);
  const armMaterial = new THREE.MeshStandardMaterial({ color: 0x667085 });
  for (const angle of [Math.PI / 4, -Math.PI / 4]) {
    const arm = new THREE.Mesh(new THREE.BoxGeometry(0.07, 0.05, 1.7), armMaterial);
    arm.rotation.y = angle;
    drone.add(arm);
  }
  const front = new THREE.MeshStandardMaterial({ color: 0xf79009, transparent: true, opacity: 0.75 });
  const rear = new THREE.MeshStandardMaterial({ color: 0x2358d6, transparent: true, opacity: 0.6 });
  const reach = 0.6;
  for (const [x, z] of [[reach, -reach], [-reach, -reach], [reach, reach], [-reach, reach]]) {
    const rotor = new THREE.Mesh(new THREE.CylinderGeometry(0.3, 0.3, 0.03, 32), z < 0 ? front : rear);
    rotor.position.set(x, 0.09, z);
    drone.add(rotor);
    const hub = new THREE.Mesh(new THREE.CylinderGeometry(0.05, 0.05, 0.12, 12), dark);
    hub.position.set(x, 0.04, z);
    drone.add(hub);
  }
  return drone;
}
