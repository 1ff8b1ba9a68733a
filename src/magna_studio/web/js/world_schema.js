// What the world form shows for each part of a world document (the ROS-MAGNA format as magna_worlds reads it:
// DESIGN.md "File formats", src/magna_worlds/README.md), and the parts the Add buttons insert.
// The server's check is the judge of every value; these lists only decide which inputs to offer.

export const SHAPES = ["cube", "sphere", "cylinder", "torus", "prism"];
export const POSE_SET_TYPES = ["matrix", "random", "coordinates", "zigzag"];
export const POSE_SET_USES = ["poses", "obstacles"];

const XYZ = ["x", "y", "z"];
const RPY = ["roll", "pitch", "yaw"];

/** What a shape's `dimensions` mean (full sizes, as rviz scales). */
const SHAPE_DIMENSIONS = {
  cube: { axes: ["x", "y", "z"], doc: "full sizes along x, y, z (m)" },
  sphere: { axes: ["x", "y", "z"], doc: "diameters along x, y, z (m)" },
  cylinder: { axes: ["x", "y", "height"], doc: "diameters along x, y and the height (m)" },
  torus: { axes: ["outer", "outer", "tube"], doc: "outer diameter (twice), tube diameter (m)" },
};

const frameField = (path, label) => ({
  path, label, kind: "matrix", rows: 2, cols: 3, axes: [...XYZ, ...RPY],
  doc: "[[x, y, z], [roll, pitch, yaw]] in the parent frame (m, rad)",
});

/** Fields of `scenario`. */
export function scenarioFields(base) {
  return [
    { path: `${base}.world_boundaries`, label: "world_boundaries", kind: "matrix", rows: 3, cols: 2,
      axes: ["x min", "x max", "y min", "y max", "z min", "z max"], optional: true,
      doc: "[[xmin, xmax], [ymin, ymax], [zmin, zmax]] (m); left out, the box around every geometry plus 10 m" },
    { path: `${base}.origin_geo`, label: "origin_geo", kind: "vector", size: 3, axes: ["lat", "lon", "alt"], optional: true,
      doc: "latitude, longitude (degrees), altitude (m) of the map origin" },
  ];
}

/** A volume that includes another file: {"name": "JSON", "world": W, "subworld": S}. */
export const isInclude = (volume) => volume && typeof volume === "object" && ("world" in volume || "subworld" in volume);

export function volumeFields(base, volume) {
  if (isInclude(volume)) {
    return [
      { path: `${base}.name`, label: "name", kind: "text", doc: "\"JSON\": the volumes come from another world file" },
      { path: `${base}.world`, label: "world", kind: "text", doc: "the included file's world (folder)" },
      { path: `${base}.subworld`, label: "subworld", kind: "text", doc: "the included file's name without .json" },
    ];
  }
  return [
    { path: `${base}.name`, label: "name", kind: "text", doc: "the volume's frame name" },
    { path: `${base}.prefix`, label: "prefix", kind: "text", optional: true, doc: "starts its frames' names" },
    frameField(`${base}.origin`, "origin"),
    { path: `${base}.permits`, label: "permits", kind: "text", optional: true, doc: "e.g. geofence" },
  ];
}

export function geometryFields(base, geometry) {
  const shape = geometry && geometry.shape;
  const fields = [
    { path: `${base}.name`, label: "name", kind: "text" },
    { path: `${base}.prefix`, label: "prefix", kind: "text", optional: true },
    { path: `${base}.shape`, label: "shape", kind: "choice", choices: SHAPES, structural: true },
    { path: `${base}.id`, label: "id", kind: "number", optional: true },
    frameField(`${base}.origin`, "origin"),
  ];
  if (shape === "prism") {
    fields.push({ path: `${base}.dimensions`, label: "dimensions", kind: "json",
      doc: "[height, [[x, y, z], ...]]: the height (m) and the base polygon's vertices" });
  } else {
    const meaning = SHAPE_DIMENSIONS[shape] || SHAPE_DIMENSIONS.cube;
    fields.push({ path: `${base}.dimensions`, label: "dimensions", kind: "vector", size: 3, axes: meaning.axes, doc: meaning.doc });
  }
  fields.push(
    { path: `${base}.color`, label: "color", kind: "color", doc: "r, g, b (0-255)" },
    { path: `${base}.alpha`, label: "alpha", kind: "number", doc: "opacity 0-1" },
  );
  return fields;
}

export function poseSetFields(base, set) {
  const type = set && set.type;
  const fields = [
    { path: `${base}.type`, label: "type", kind: "choice", choices: POSE_SET_TYPES, structural: true },
    { path: `${base}.use`, label: "use", kind: "choice", choices: POSE_SET_USES, structural: true,
      doc: "poses to fly to, or obstacles laid out the same way" },
  ];
  if (type === "matrix") {
    fields.push(
      { path: `${base}.matrix_type`, label: "matrix_type", kind: "choice", choices: ["dimension", "distance"], optional: true,
        doc: "dimension: counts per axis; distance: cell sizes (m)" },
      { path: `${base}.dimensions`, label: "dimensions", kind: "vector", size: 3, axes: ["i", "j", "k"] },
      { path: `${base}.density`, label: "density", kind: "number", optional: true, doc: "chance each cell is kept (0-1)" },
    );
  } else if (type === "random") {
    fields.push({ path: `${base}.quantity`, label: "quantity", kind: "number", doc: "how many poses" });
  } else if (type === "coordinates") {
    fields.push({ path: `${base}.coordinates`, label: "coordinates", kind: "json",
      doc: "[[[x, y, z], [r, p, y]], ...] in the geometry's frame" });
  } else if (type === "zigzag") {
    fields.push(
      { path: `${base}.height`, label: "height", kind: "number", doc: "above the base (m)" },
      { path: `${base}.spacing`, label: "spacing", kind: "vector", size: 2, axes: ["along", "between"], doc: "m" },
      { path: `${base}.sweep_angle`, label: "sweep_angle", kind: "number", doc: "direction of the lines (rad)" },
      { path: `${base}.margins`, label: "margins", kind: "vector", size: 2, axes: ["ends", "sides"], doc: "m" },
      { path: `${base}.initial_sense`, label: "initial_sense", kind: "choice", choices: ["right", "left"] },
    );
  }
  fields.push(
    { path: `${base}.poses_orientation`, label: "poses_orientation", kind: "json", optional: true,
      doc: "[r, p, y], per-axis ranges [[lo, hi] x 3], \"random_yaw\" or \"random\"" },
    { path: `${base}.set_orientation`, label: "set_orientation", kind: "vector", size: 3, axes: RPY, optional: true,
      doc: "turns the set (its yaw turns a prism's grid)" },
  );
  if (set && set.use === "obstacles") {
    fields.push(
      { path: `${base}.obstacles_shape`, label: "obstacles_shape", kind: "json", doc: "shapes drawn from, e.g. [\"cube\"]" },
      { path: `${base}.obstacles_dimensions`, label: "obstacles_dimensions", kind: "json",
        doc: "[d0, d1, d2] or per obstacle [[lo, hi] x 3]" },
    );
  }
  return fields;
}

// --- what the Add buttons insert ------------------------------------------------------------------------------------

export function newVolume(index) {
  return { name: `Volume_${index}`, prefix: `V${index}`, origin: [[0, 0, 0], [0, 0, 0]], permits: "geofence", geometries: [] };
}

export function newGeometry(index) {
  return {
    name: `Geometry_${index}`, prefix: `g${index}`, shape: "cube", id: 0, origin: [[0, 0, 1], [0, 0, 0]],
    dimensions: [2, 2, 2], color: [90, 170, 250], alpha: 0.2, poses_sets: [],
  };
}

export function newPoseSet() {
  return { type: "matrix", matrix_type: "dimension", use: "poses", dimensions: [2, 2, 1], density: 1,
    poses_orientation: [0, 0, 0], set_orientation: [0, 0, 0] };
}

/** Defaults a pose set needs when its type changes (only keys it lacks are added). */
export const POSE_SET_TYPE_DEFAULTS = {
  matrix: { matrix_type: "dimension", dimensions: [2, 2, 1], density: 1 },
  random: { quantity: 5 },
  coordinates: { coordinates: [[[0, 0, 0], [0, 0, 0]]] },
  zigzag: { height: 1, spacing: [0, 2], sweep_angle: 0, margins: [0.5, 0.5], initial_sense: "right" },
};

/** Dimensions that fit a shape when the shape changes (a prism's differ in form). */
export function dimensionsForShape(shape, previous) {
  if (shape === "prism") return [2, [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]];
  if (Array.isArray(previous) && previous.length === 3 && previous.every((n) => typeof n === "number")) return previous;
  return [2, 2, 2];
}

export const OBSTACLE_DEFAULTS = { obstacles_shape: ["cube"], obstacles_dimensions: [0.5, 0.5, 0.5] };
