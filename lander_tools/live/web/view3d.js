// The student page's 3-D view of a flight (docs/live.md), drawn with three.js (shipped in this
// folder: three.module.min.js r170, OrbitControls.js; MIT licence in three.LICENSE).
//
// What it draws comes from the state records of /live/state (lander_tools/live/views.py):
// the body (a box L x L x 0.6 L) at position_S in the orientation q_SB (base_link in the local
// surface frame, z up), one cone per lit plume from its start to its end (body frame, length
// 2 L x throttle: lander_sim/look.py), the canopy when open, the trail, the ground, and for a
// fixed-pivot body (the rotor scenes) the track of its z axis tip. Far from the ground (altitude
// above PLANET_VIEW_ALTITUDE) it draws the planet and the orbit at scale instead, in the world
// frame (km), the lander enlarged to stay visible.
import * as THREE from "three";
import { OrbitControls } from "./OrbitControls.js";

export const PLANET_VIEW_ALTITUDE = 20e3;   // [m] above it: the planet view (no ground nearby)
const MARS_RADIUS = 3386e3;                // [m] lander_sim/physics/constants.py
const KM = 1e-3;                           // planet view units: km
const TRAIL_MAX = 20000;                   // points kept in a trail line (the oldest dropped)

function polyline(color, max) {
  const geom = new THREE.BufferGeometry();
  geom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3 * max), 3));
  geom.setDrawRange(0, 0);
  const line = new THREE.Line(geom, new THREE.LineBasicMaterial({ color }));
  line.frustumCulled = false;
  return { line, n: 0, max, geom };
}

function push(pl, x, y, z) {
  const a = pl.geom.attributes.position.array;
  if (pl.n === pl.max) { a.copyWithin(0, 3); pl.n -= 1; }
  a[3 * pl.n] = x; a[3 * pl.n + 1] = y; a[3 * pl.n + 2] = z;
  pl.n += 1;
  pl.geom.setDrawRange(0, pl.n);
  pl.geom.attributes.position.needsUpdate = true;
}

function clear(pl) { pl.n = 0; pl.geom.setDrawRange(0, 0); }

export class View3D {
  constructor(canvas) {
    this.canvas = canvas;
    // No multisampling: in a software renderer (headless, SwiftShader) it costs more than the view gains.
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(1);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x0b0d12);
    this.camera = new THREE.PerspectiveCamera(50, canvas.width / canvas.height, 0.05, 5e7);
    this.camera.up.set(0, 0, 1);              // surface frame: z up
    this.camera.position.set(8, -10, 5);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.autoRotateSpeed = 1.5;
    this.scene.add(new THREE.AmbientLight(0xffffff, 0.6));
    const sun = new THREE.DirectionalLight(0xffffff, 2.0);
    sun.position.set(3, -2, 5);
    this.scene.add(sun);
    this.mode = "follow";                     // follow | orbit | free
    this.view = "local";                      // local | planet

    // Local view: ground, trail, z-axis track, the lander.
    this.local = new THREE.Group();
    this.ground = new THREE.Mesh(new THREE.PlaneGeometry(4000, 4000),
                                 new THREE.MeshStandardMaterial({ color: 0x8a4a2a, roughness: 1 }));
    this.grid = new THREE.GridHelper(400, 40, 0xb06040, 0x9a5535);
    this.grid.rotation.x = Math.PI / 2;       // GridHelper lies in x-z: turn it into x-y
    this.grid.position.z = 0.02;
    this.local.add(this.ground, this.grid);
    this.trail = polyline(0x3399ff, TRAIL_MAX);
    this.ztrack = polyline(0x66ff99, TRAIL_MAX);
    this.local.add(this.trail.line, this.ztrack.line);
    this.scene.add(this.local);

    // Planet view: the planet and the orbit (km), world frame.
    this.planet = new THREE.Group();
    this.planet.add(new THREE.Mesh(new THREE.SphereGeometry(MARS_RADIUS * KM, 96, 48),
                                   new THREE.MeshStandardMaterial({ color: 0xa0522d, roughness: 1 })));
    this.orbit = polyline(0x3399ff, TRAIL_MAX);
    this.planet.add(this.orbit.line);
    this.planet.visible = false;
    this.scene.add(this.planet);

    this.lander = new THREE.Group();          // base_link
    this.body = new THREE.Mesh(new THREE.BoxGeometry(1, 1, 0.6),
                               new THREE.MeshStandardMaterial({ color: 0xcccccc, metalness: 0.2, roughness: 0.5 }));
    this.lander.add(this.body);
    const axis = new THREE.Mesh(new THREE.CylinderGeometry(0.03, 0.03, 1, 8),
                                new THREE.MeshStandardMaterial({ color: 0x66ff99 }));
    axis.rotation.x = Math.PI / 2; axis.position.z = 0.8; axis.scale.set(1, 1.0, 1);
    this.lander.add(axis);                    // the body z axis, so the attitude reads at a glance
    this.plumeMaterial = new THREE.MeshBasicMaterial({ color: 0xff8020, transparent: true, opacity: 0.9 });
    this.plumes = [];
    this.canopy = new THREE.Mesh(new THREE.SphereGeometry(0.5, 24, 12),
                                 new THREE.MeshStandardMaterial({ color: 0xe6e6ff, transparent: true, opacity: 0.7 }));
    this.canopy.visible = false;
    this.lander.add(this.canopy);
    this.scene.add(this.lander);
    this.last = null;
    this.resize();
  }

  setMode(mode) {
    this.mode = mode;
    this.controls.autoRotate = mode === "orbit";
  }

  resize() {
    const w = this.canvas.clientWidth || this.canvas.width, h = this.canvas.clientHeight || this.canvas.height;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  clearTrail() { clear(this.trail); clear(this.ztrack); clear(this.orbit); }

  // One state record (lander_tools/live/views.py: state_record + view_fields).
  update(r) {
    if (!r.position_S || !r.q_SB) return;
    if (this.last && r.t < this.last.t) this.clearTrail();   // a reset: a new epoch
    const L = r.size || 1;
    const planet = r.altitude > PLANET_VIEW_ALTITUDE;
    if (planet !== (this.view === "planet")) this.switchView(planet ? "planet" : "local", r);
    const [x, y, z] = r.position_S;
    push(this.trail, x, y, z);
    if (r.fixed_pivot && r.up_S) push(this.ztrack, x + 2 * L * r.up_S[0], y + 2 * L * r.up_S[1], z + 2 * L * r.up_S[2]);
    if (r.position_W) push(this.orbit, r.position_W[0] * KM, r.position_W[1] * KM, r.position_W[2] * KM);
    let moved;
    if (this.view === "local") {
      moved = new THREE.Vector3(x, y, z).sub(this.lander.position);
      this.lander.position.set(x, y, z);
      this.lander.quaternion.set(r.q_SB[0], r.q_SB[1], r.q_SB[2], r.q_SB[3]);
      this.lander.scale.setScalar(L);
      this.ground.position.set(x, y, 0);      // the ground stays under the lander, the grid marks the place
      this.grid.position.set(Math.round(x / 10) * 10, Math.round(y / 10) * 10, 0.02);
    } else {
      const p = r.position_W.map((v) => v * KM);
      moved = new THREE.Vector3(...p).sub(this.lander.position);
      this.lander.position.set(...p);
      this.lander.quaternion.set(r.q_WB[0], r.q_WB[1], r.q_WB[2], r.q_WB[3]);
      this.lander.scale.setScalar(0.02 * this.camera.position.distanceTo(this.lander.position));
    }
    this.drawPlumes(r.plumes_B || []);
    this.canopy.visible = !!r.parachute_B;
    if (r.parachute_B) {
      const c = r.parachute_B;
      this.canopy.position.set(c[0] / L, c[1] / L, c[2] / L);   // the lander group is scaled by L
      this.canopy.scale.set(c[3] / L, c[4] / L, c[5] / L);
    }
    if (this.mode !== "free") {               // follow (and orbit): the camera keeps its offset
      this.camera.position.add(moved);
      this.controls.target.copy(this.lander.position);
    }
    this.last = r;
  }

  drawPlumes(plumes) {
    const L = this.lander.scale.x || 1;
    while (this.plumes.length < plumes.length) {
      const cone = new THREE.Mesh(new THREE.ConeGeometry(0.075, 1, 16), this.plumeMaterial);
      this.plumes.push(cone); this.lander.add(cone);
    }
    const up = new THREE.Vector3(0, 1, 0);
    this.plumes.forEach((cone, i) => {
      const p = plumes[i];
      cone.visible = !!p;
      if (!p) return;
      // Body frame [m] / L: the group is scaled by L. The cone's apex (+y) at the plume's far end.
      const a = new THREE.Vector3(p[0], p[1], p[2]).divideScalar(L);
      const b = new THREE.Vector3(p[3], p[4], p[5]).divideScalar(L);
      const d = b.clone().sub(a);
      const len = d.length();
      cone.position.copy(a.clone().add(b).multiplyScalar(0.5));
      cone.quaternion.setFromUnitVectors(up, d.normalize());
      cone.scale.set(1, len, 1);
    });
  }

  switchView(view, r) {
    this.view = view;
    this.local.visible = view === "local";
    this.planet.visible = view === "planet";
    if (view === "planet") {                  // the whole planet and the orbit in sight
      const p = new THREE.Vector3(...r.position_W).multiplyScalar(KM);
      this.lander.position.copy(p);
      this.camera.position.copy(p.clone().normalize().multiplyScalar(3.5 * MARS_RADIUS * KM));
      this.camera.up.set(0, 0, 1);
    } else {
      this.lander.position.set(...r.position_S);
      this.camera.position.set(r.position_S[0] + 8, r.position_S[1] - 10, r.position_S[2] + 5);
    }
    this.controls.target.copy(this.lander.position);
  }

  render() {
    this.controls.update();
    this.renderer.render(this.scene, this.camera);
  }

  // What the view draws now, for the browser test: the body's pose and its z axis in the
  // surface frame (local view), the lit plumes, the canopy, the trail's length.
  state() {
    const zAxis = new THREE.Vector3(0, 0, 1).applyQuaternion(this.lander.quaternion);
    const q = this.lander.quaternion;
    return { view: this.view, mode: this.mode, position: this.lander.position.toArray(), quaternion: [q.x, q.y, q.z, q.w],
             z_axis: zAxis.toArray(), plumes: this.plumes.filter((c) => c.visible).length,
             canopy: this.canopy.visible, trail: this.trail.n, ztrack: this.ztrack.n, t: this.last ? this.last.t : null };
  }
}
