// The 3-D view of a world (three.js): the scene the server lays out, drawn with the primitives rviz markers
// use (CUBE/SPHERE/CYLINDER sized by scale, point and line lists, triangle lists), z up as in ROS (ENU).
// Geometries are translucent in their colour, obstacles solid, pose sets points, the boundaries a wire box.
// UAVs and their trails are for the Run view: setUav(id, position, color), setTrail(id, points).
// Drawn on demand (after a change or a camera move), not in a loop: the machine is shared with simulations.

import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { isAncestorOrSelf } from "./json_path.js";

const BACKGROUND = 0xf4f5f7;
const BOUNDARY_COLOR = 0x5b6270;
const HIGHLIGHT_COLOR = 0xff8c1a;
const POINT_PIXELS = 7;
const MIN_GEOMETRY_OPACITY = 0.08; // a geometry of alpha 0 would vanish; keep it faintly visible
const MIN_LIGHT_OPACITY = 0.22; // a near-white part needs more to show on the light background
const LIGHT_PART_SHADE = 0.7; // ... and a little grey
const CLICK_TOLERANCE_PX = 4; // a press that moves less than this is a click (pick), not an orbit

/** true when this browser can draw WebGL. */
export function webglAvailable() {
  try {
    const canvas = document.createElement("canvas");
    return Boolean(canvas.getContext("webgl2") || canvas.getContext("webgl"));
  } catch {
    return false;
  }
}

/** [r, g, b, a?] in 0..1 or 0..255 (or a CSS colour) -> {color, opacity}. */
function readColor(value, fallbackOpacity = 1) {
  if (typeof value === "string") return { color: new THREE.Color(value), opacity: fallbackOpacity };
  const rgba = Array.isArray(value) ? value.map(Number) : [0.5, 0.5, 0.5];
  const scale = rgba.slice(0, 3).some((c) => c > 1) ? 255 : 1;
  const color = new THREE.Color().setRGB((rgba[0] || 0) / scale, (rgba[1] || 0) / scale, (rgba[2] || 0) / scale,
    THREE.SRGBColorSpace);
  const alpha = rgba.length > 3 && Number.isFinite(rgba[3]) ? rgba[3] : fallbackOpacity;
  return { color, opacity: Math.max(0, Math.min(1, alpha)) };
}

const vector = (value, fallback) => (Array.isArray(value) && value.length >= 3 ? value.slice(0, 3).map(Number) : fallback);

function roundPointTexture() {
  const size = 64;
  const canvas = document.createElement("canvas");
  canvas.width = canvas.height = size;
  const context = canvas.getContext("2d");
  context.beginPath();
  context.arc(size / 2, size / 2, size / 2 - 2, 0, 2 * Math.PI);
  context.fillStyle = "#ffffff";
  context.fill();
  const texture = new THREE.CanvasTexture(canvas);
  texture.colorSpace = THREE.SRGBColorSpace;
  return texture;
}

export class WorldView {
  /** Draws into `container`; `onPick(path)` when the user clicks a part of the world. */
  constructor(container, { onPick } = {}) {
    this.container = container;
    this.onPick = onPick || (() => {});
    this.available = webglAvailable();
    this.items = []; // [{path, objects: [Object3D], highlight(on)}]
    this.uavs = new Map(); // id -> {marker, trail}
    this.bounds = null;
    this.highlighted = null;
    if (!this.available) {
      const note = document.createElement("p");
      note.className = "view-unavailable";
      note.textContent = "The 3-D view needs WebGL, which this browser does not offer; the forms and checks still work.";
      container.append(note);
      return;
    }
    this.renderer = new THREE.WebGLRenderer({ antialias: true });
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.domElement.setAttribute("aria-label", "3-D view of the world: drag to orbit, wheel to zoom, right-drag to pan");
    this.renderer.domElement.tabIndex = 0;
    container.append(this.renderer.domElement);

    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(BACKGROUND);
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.05, 5000);
    this.camera.up.set(0, 0, 1); // ROS ENU: z is up
    this.camera.position.set(-15, -20, 15);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener("change", () => this.requestRender());
    this.controls.listenToKeyEvents(this.renderer.domElement); // arrow keys pan when the canvas has focus

    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f99, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(-0.5, -0.8, 1.5);
    this.scene.add(sun);

    this.worldGroup = new THREE.Group(); // what setScene draws
    this.uavGroup = new THREE.Group(); // what the Run view adds
    this.scene.add(this.worldGroup, this.uavGroup);
    this.pointTexture = roundPointTexture();

    this.#listenForPicks();
    this.resizeObserver = new ResizeObserver(() => this.#resize());
    this.resizeObserver.observe(container);
    this.#resize();
  }

  // --- the world ---------------------------------------------------------------------------------------------------

  /** Draw scene S ({boundaries, items}); null clears the world (UAVs stay). */
  setScene(scene) {
    if (!this.available) return;
    const firstScene = this.bounds === null;
    this.#clearGroup(this.worldGroup);
    this.items = [];
    const box = new THREE.Box3();
    if (scene && Array.isArray(scene.boundaries) && scene.boundaries.length === 3) {
      const [[x0, x1], [y0, y1], [z0, z1]] = scene.boundaries.map((pair) => pair.map(Number));
      box.set(new THREE.Vector3(x0, y0, z0), new THREE.Vector3(x1, y1, z1));
      this.#addBoundaries(box);
    }
    for (const item of (scene && Array.isArray(scene.items) ? scene.items : [])) {
      const objects = this.#objectsOf(item);
      if (!objects.length) continue;
      for (const object of objects) {
        object.userData.path = item.path || "";
        this.worldGroup.add(object);
      }
      this.items.push({ path: item.path || "", kind: item.kind || "", objects });
    }
    if (box.isEmpty()) box.setFromObject(this.worldGroup);
    this.bounds = box.isEmpty() ? null : box;
    this.#addGround();
    this.highlight(this.highlighted);
    if (firstScene) this.fit();
    this.requestRender();
  }

  /** Emphasise the parts whose path is `path` or below it (a volume: its geometries; null: none). */
  highlight(path) {
    this.highlighted = path;
    if (!this.available) return;
    for (const item of this.items) {
      const on = path !== null && path !== undefined && path !== "" && isAncestorOrSelf(path, item.path);
      for (const object of item.objects) object.userData.setHighlight?.(on);
    }
    this.requestRender();
  }

  /** Point the camera at the whole world (its boundaries, else everything drawn). */
  fit() {
    if (!this.available) return;
    const box = this.bounds ? this.bounds.clone() : new THREE.Box3().setFromObject(this.scene);
    if (box.isEmpty()) box.set(new THREE.Vector3(-5, -5, 0), new THREE.Vector3(5, 5, 5));
    const sphere = box.getBoundingSphere(new THREE.Sphere());
    const radius = Math.max(sphere.radius, 1);
    const halfFov = THREE.MathUtils.degToRad(this.camera.fov / 2);
    // the bounding sphere overestimates a box seen from a corner: come a little closer than it says
    const halfFovAcross = Math.atan(Math.tan(halfFov) * this.camera.aspect);
    const distance = (radius / Math.sin(Math.min(halfFov, halfFovAcross))) * 0.9;
    const direction = new THREE.Vector3(-0.55, -1, 0.75).normalize();
    this.camera.position.copy(sphere.center).addScaledVector(direction, distance);
    this.camera.near = Math.max(distance / 1000, 0.01);
    this.camera.far = distance * 10 + radius * 4;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(sphere.center);
    this.controls.update();
    this.requestRender();
  }

  // --- UAVs (the Run view) -----------------------------------------------------------------------------------------

  /** Place UAV `id` at [x, y, z] (map frame), drawn in `color` ([r, g, b(, a)] 0..1 or 0..255, or CSS). */
  setUav(id, position, color) {
    if (!this.available) return;
    let uav = this.uavs.get(id);
    const { color: tint } = readColor(color ?? [0.85, 0.1, 0.1], 1);
    if (!uav) {
      const size = this.#uavSize();
      const marker = new THREE.Mesh(new THREE.SphereGeometry(size, 20, 14), new THREE.MeshStandardMaterial({ color: tint }));
      marker.name = `uav_${id}`;
      this.uavGroup.add(marker);
      uav = { marker, trail: null };
      this.uavs.set(id, uav);
    }
    uav.marker.material.color.copy(tint);
    uav.marker.position.set(...vector(position, [0, 0, 0]));
    this.requestRender();
  }

  /** The path UAV `id` has flown: [[x, y, z], ...] (replaces the previous one). */
  setTrail(id, points) {
    if (!this.available) return;
    const uav = this.uavs.get(id);
    const color = uav ? uav.marker.material.color : new THREE.Color(0.85, 0.1, 0.1);
    const positions = (points || []).map((p) => vector(p, [0, 0, 0])).flat();
    let trail = uav ? uav.trail : this.uavGroup.getObjectByName(`trail_${id}`);
    if (!trail) {
      trail = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color }));
      trail.name = `trail_${id}`;
      trail.frustumCulled = false; // its bounding sphere changes every update
      this.uavGroup.add(trail);
      if (uav) uav.trail = trail;
    }
    trail.geometry.setAttribute("position", new THREE.Float32BufferAttribute(positions, 3));
    trail.geometry.computeBoundingSphere();
    this.requestRender();
  }

  removeUav(id) {
    const uav = this.uavs.get(id);
    if (!uav) return;
    for (const object of [uav.marker, uav.trail]) {
      if (!object) continue;
      this.uavGroup.remove(object);
      object.geometry.dispose();
      object.material.dispose();
    }
    this.uavs.delete(id);
    this.requestRender();
  }

  clearUavs() {
    for (const id of [...this.uavs.keys()]) this.removeUav(id);
    this.#clearGroup(this.uavGroup);
  }

  // --- drawing -----------------------------------------------------------------------------------------------------

  requestRender() {
    if (!this.available || this.renderPending) return;
    this.renderPending = true;
    requestAnimationFrame(() => {
      this.renderPending = false;
      this.renderer.render(this.scene, this.camera);
    });
  }

  dispose() {
    if (!this.available) return;
    this.resizeObserver.disconnect();
    this.controls.dispose();
    this.#clearGroup(this.worldGroup);
    this.clearUavs();
    this.renderer.dispose();
    this.renderer.domElement.remove();
  }

  #uavSize() {
    const span = this.bounds ? this.bounds.getSize(new THREE.Vector3()).length() : 20;
    return Math.max(0.25, span * 0.006);
  }

  #resize() {
    const width = Math.max(1, this.container.clientWidth);
    const height = Math.max(1, this.container.clientHeight);
    this.renderer.setSize(width, height, false);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  #addBoundaries(box) {
    const size = box.getSize(new THREE.Vector3());
    const edges = new THREE.EdgesGeometry(new THREE.BoxGeometry(size.x, size.y, size.z));
    const wire = new THREE.LineSegments(edges, new THREE.LineBasicMaterial({ color: BOUNDARY_COLOR }));
    wire.position.copy(box.getCenter(new THREE.Vector3()));
    wire.name = "boundaries";
    this.worldGroup.add(wire);
  }

  /** A grid on the floor of the world (z of its lowest boundary) and the map axes. */
  #addGround() {
    const box = this.bounds;
    if (!box) return;
    const size = box.getSize(new THREE.Vector3());
    const span = Math.max(size.x, size.y, 1);
    const step = [1, 2, 5, 10, 20, 50, 100].find((s) => span / s <= 60) || 200;
    const divisions = Math.ceil(span / step);
    const grid = new THREE.GridHelper(divisions * step, divisions, 0xc3c7cf, 0xdfe2e7);
    grid.rotation.x = Math.PI / 2; // GridHelper lies in x-z; the floor here is x-y
    const centre = box.getCenter(new THREE.Vector3());
    grid.position.set(centre.x, centre.y, box.min.z);
    grid.name = "ground";
    const axes = new THREE.AxesHelper(Math.max(1, span * 0.05));
    axes.name = "map axes";
    this.worldGroup.add(grid, axes);
  }

  /** The three.js objects of one scene item (empty for a shape this view does not know). */
  #objectsOf(item) {
    const shape = String(item.shape || "").toLowerCase();
    const kind = String(item.kind || "").toLowerCase();
    const obstacle = kind.startsWith("obstacle");
    const { color, opacity } = readColor(item.color, 1);
    const position = vector(item.position, [0, 0, 0]);
    const orientation = Array.isArray(item.orientation) && item.orientation.length === 4 ? item.orientation.map(Number) : [0, 0, 0, 1];
    const scale = vector(item.scale, [1, 1, 1]);
    const place = (object, scaled = true) => {
      object.position.set(...position);
      object.quaternion.set(...orientation);
      if (scaled) object.scale.set(...scale);
      object.name = item.name || "";
      return object;
    };
    const points = Array.isArray(item.points) ? item.points.map((p) => vector(p, [0, 0, 0])) : [];

    if (shape === "cube" || shape === "sphere" || shape === "cylinder" || shape === "triangles"
        || shape === "triangle_list" || shape === "mesh") {
      let geometry;
      if (shape === "cube") geometry = new THREE.BoxGeometry(1, 1, 1);
      else if (shape === "sphere") geometry = new THREE.SphereGeometry(0.5, 32, 20);
      else if (shape === "cylinder") geometry = new THREE.CylinderGeometry(0.5, 0.5, 1, 40).rotateX(Math.PI / 2); // rviz: axis z
      else {
        if (points.length < 3) return [];
        geometry = new THREE.BufferGeometry();
        geometry.setAttribute("position", new THREE.Float32BufferAttribute(points.slice(0, points.length - (points.length % 3)).flat(), 3));
        geometry.computeVertexNormals();
      }
      const solid = obstacle || opacity >= 0.99;
      // rviz draws on a dark background; on this light one a near-white translucent part would vanish
      const light = color.getHSL({}).l > 0.8;
      const shown = light && !solid ? color.clone().multiplyScalar(LIGHT_PART_SHADE) : color;
      const material = new THREE.MeshStandardMaterial({
        color: shown, roughness: 0.8, metalness: 0.0, side: THREE.DoubleSide, transparent: !solid,
        opacity: solid ? 1 : Math.max(opacity, light ? MIN_LIGHT_OPACITY : MIN_GEOMETRY_OPACITY), depthWrite: solid,
      });
      const mesh = place(new THREE.Mesh(geometry, material));
      const edgeColor = obstacle || light ? shown.clone().multiplyScalar(0.6) : color;
      const edges = new THREE.LineSegments(new THREE.EdgesGeometry(geometry, 25),
        new THREE.LineBasicMaterial({ color: edgeColor, transparent: !solid, opacity: solid ? 1 : 0.6 }));
      mesh.add(edges);
      mesh.userData.pickable = true;
      mesh.userData.setHighlight = (on) => {
        material.emissive.set(on ? HIGHLIGHT_COLOR : 0x000000);
        material.emissiveIntensity = on ? 0.35 : 0;
        edges.material.color.set(on ? HIGHLIGHT_COLOR : edgeColor);
        edges.material.opacity = on ? 1 : solid ? 1 : 0.6;
      };
      return [mesh];
    }
    if (shape === "points" || shape === "sphere_list" || shape === "cube_list" || shape === "point_list") {
      if (!points.length) return [];
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute("position", new THREE.Float32BufferAttribute(points.flat(), 3));
      const material = new THREE.PointsMaterial({
        color, size: POINT_PIXELS, sizeAttenuation: false, map: this.pointTexture, alphaTest: 0.5, transparent: false,
      });
      const cloud = place(new THREE.Points(geometry, material), false);
      cloud.userData.setHighlight = (on) => {
        material.color.copy(on ? new THREE.Color(HIGHLIGHT_COLOR) : color);
        material.size = on ? POINT_PIXELS * 1.5 : POINT_PIXELS;
      };
      return [cloud];
    }
    if (shape === "line" || shape === "line_strip" || shape === "line_list") {
      if (points.length < 2) return [];
      const geometry = new THREE.BufferGeometry().setFromPoints(points.map((p) => new THREE.Vector3(...p)));
      const material = new THREE.LineBasicMaterial({ color, transparent: opacity < 1, opacity });
      const line = place(shape === "line_list" ? new THREE.LineSegments(geometry, material) : new THREE.Line(geometry, material), false);
      line.userData.setHighlight = (on) => material.color.copy(on ? new THREE.Color(HIGHLIGHT_COLOR) : color);
      return [line];
    }
    return [];
  }

  #clearGroup(group) {
    for (const child of [...group.children]) {
      group.remove(child);
      child.traverse((object) => {
        object.geometry?.dispose();
        if (object.material) [].concat(object.material).forEach((material) => material.dispose());
      });
    }
  }

  /** A click (not a drag) on a geometry or obstacle tells onPick its JSON path. */
  #listenForPicks() {
    const canvas = this.renderer.domElement;
    let down = null;
    canvas.addEventListener("pointerdown", (event) => { down = { x: event.clientX, y: event.clientY }; });
    canvas.addEventListener("pointerup", (event) => {
      if (!down || Math.hypot(event.clientX - down.x, event.clientY - down.y) > CLICK_TOLERANCE_PX) return;
      down = null;
      const rect = canvas.getBoundingClientRect();
      const pointer = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1,
        -((event.clientY - rect.top) / rect.height) * 2 + 1);
      const raycaster = new THREE.Raycaster();
      raycaster.setFromCamera(pointer, this.camera);
      const pickable = this.worldGroup.children.filter((object) => object.userData.pickable);
      const hit = raycaster.intersectObjects(pickable, false)[0];
      if (hit && hit.object.userData.path) this.onPick(hit.object.userData.path);
    });
  }
}
