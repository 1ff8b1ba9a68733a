// The World view: open or create a world document, edit it part by part (tree + form), see it in 3-D,
// and check it live: every edit changes the document, then (once typing pauses) the server checks it, the
// scene is redrawn and each diagnostic is shown on its field and in the list.

import * as api from "./api.js";
import { byTestId } from "./dom.js";
import { countByItem, renderDiagnosticsList, showFieldErrors, summarise } from "./diagnostics.js";
import { setUpFilePicker } from "./file_picker.js";
import { BoundForm, objectErrorsRow } from "./form.js";
import { childPath, getAt, nearestPath, parsePath, formatPath } from "./json_path.js";
import { LiveCheck } from "./live_check.js";
import { defaultSavePath, saveFromToolbar } from "./save.js";
import { session } from "./session.js";
import { showError, showStatus } from "./status.js";
import { Tree } from "./tree.js";
import {
  dimensionsForShape, geometryFields, isInclude, newGeometry, newPoseSet, newVolume, OBSTACLE_DEFAULTS,
  POSE_SET_TYPE_DEFAULTS, poseSetFields, scenarioFields, volumeFields,
} from "./world_schema.js";
import { WorldView } from "./world_view.js";

const ROOT = "scenario";

/** The kind of part a tree path names: scenario, volume, geometry or poseSet. */
function partKind(path) {
  const parts = parsePath(path);
  return { 1: "scenario", 3: "volume", 5: "geometry", 7: "poseSet" }[parts.length] || "other";
}

/** The path of the enclosing part of `kind` ("volume" of a geometry's path: its volume), or null. */
function enclosing(path, kind) {
  const length = { volume: 3, geometry: 5 }[kind];
  const parts = parsePath(path);
  return parts.length >= length ? formatPath(parts.slice(0, length)) : null;
}

export class WorldEditor {
  constructor() {
    this.doc = null;
    this.path = null; // the file it was opened from or saved to
    this.name = null;
    this.selected = ROOT;
    this.diagnostics = [];
    this.view = new WorldView(byTestId("world-view"), { onPick: (path) => this.selectPath(path) });
    this.tree = new Tree(byTestId("world-tree"), (path) => this.selectPath(path));
    this.form = new BoundForm(byTestId("world-form"), () => this.doc, (path, how) => this.#edited(path, how));
    this.check = new LiveCheck(
      () => api.checkWorld(this.doc, this.#source(), this.#seed()),
      (answer) => this.#showCheck(answer),
      (error) => showError(error, "check failed"),
    );
    this.scene = null; // the last scene laid out (the Run view starts from it)
    /** Resolves when the file list has been asked for. */
    this.ready = setUpFilePicker(byTestId("world-spec"), byTestId("world-open"), "world", (spec) => this.open(spec));
    byTestId("world-new").addEventListener("click", () => this.create());
    byTestId("world-save").addEventListener("click", () => this.save());
    byTestId("world-save-path").addEventListener("keydown", (event) => {
      if (event.key === "Enter") this.save();
    });
    byTestId("world-fit").addEventListener("click", () => this.view.fit());
    byTestId("world-add-volume").addEventListener("click", () => this.addVolume());
    byTestId("world-add-geometry").addEventListener("click", () => this.addGeometry());
    byTestId("world-add-pose-set").addEventListener("click", () => this.addPoseSet());
    byTestId("world-remove").addEventListener("click", () => this.removeSelected());
    this.#renderAll();
  }

  // --- documents -------------------------------------------------------------------------------------------------

  async open(spec) {
    showStatus(`opening world ${spec}…`);
    try {
      const answer = await api.openWorld(spec);
      this.#load(answer.data, answer.path || null, answer.name || spec, answer.changes || []);
      this.#showCheck(answer);
      showStatus(`world ${answer.name || spec} opened (${summarise(answer.diagnostics || [])})`, "ok");
    } catch (error) {
      showError(error, `cannot open world ${spec}`);
    }
  }

  async create() {
    try {
      const answer = await api.newWorld();
      this.#load(answer.data, null, null, []);
      showStatus("new world: add volumes, geometries and pose sets, then save it", "ok");
      await this.check.now();
    } catch (error) {
      showError(error, "cannot start a new world");
    }
  }

  async save() {
    const saved = await saveFromToolbar("world", api.saveWorld, this.doc);
    if (saved === null) return;
    this.path = saved;
    this.#publish();
  }

  #load(data, path, name, changes) {
    this.check.cancel();
    this.doc = data;
    this.path = path;
    this.name = name;
    this.scene = null;
    this.selected = ROOT;
    this.diagnostics = [];
    byTestId("world-title").textContent = name || path || "new world";
    byTestId("world-save-path").value = defaultSavePath(path);
    byTestId("world-saved").textContent = "";
    this.#renderChanges(changes);
    this.view.bounds = null; // the next scene fits the camera
    this.#renderAll();
    this.#publish();
  }

  #publish() {
    session.setWorld(this.doc ? { data: this.doc, path: this.path, name: this.name, source: this.#source() } : null);
  }

  #source() {
    return this.path || this.name || "new world";
  }

  #seed() {
    return undefined; // the server's default seed; a seed field could go here
  }

  // --- editing -----------------------------------------------------------------------------------------------------

  #edited(path, { structural }) {
    if (structural) this.#applyDefaults(path);
    const labelChanged = /\.(name|shape|type|use|world|subworld)$/.test(path);
    if (structural) this.#renderForm();
    if (structural || labelChanged) this.#renderTree();
    this.#publish();
    this.check.schedule();
  }

  /** After a choice that changes what a part holds, give it the keys its new kind needs. */
  #applyDefaults(path) {
    const parent = formatPath(parsePath(path).slice(0, -1));
    const part = getAt(this.doc, parent);
    if (!part || typeof part !== "object") return;
    if (path.endsWith(".shape")) {
      part.dimensions = dimensionsForShape(part.shape, part.dimensions);
    } else if (path.endsWith(".type")) {
      for (const [key, value] of Object.entries(POSE_SET_TYPE_DEFAULTS[part.type] || {})) {
        if (!(key in part)) part[key] = structuredClone(value);
      }
    } else if (path.endsWith(".use") && part.use === "obstacles") {
      for (const [key, value] of Object.entries(OBSTACLE_DEFAULTS)) if (!(key in part)) part[key] = structuredClone(value);
    }
  }

  addVolume() {
    if (!this.#needDoc()) return;
    const scenario = this.doc.scenario || (this.doc.scenario = {});
    const volumes = Array.isArray(scenario.volumes) ? scenario.volumes : (scenario.volumes = []);
    volumes.push(newVolume(volumes.length + 1));
    this.#added(`${ROOT}.volumes[${volumes.length - 1}]`);
  }

  addGeometry() {
    if (!this.#needDoc()) return;
    const volumes = this.doc.scenario?.volumes || [];
    const volumePath = enclosing(this.selected, "volume") || (volumes.length ? `${ROOT}.volumes[${volumes.length - 1}]` : null);
    if (!volumePath) return showStatus("add a volume first: geometries live in a volume", "error");
    const volume = getAt(this.doc, volumePath);
    if (isInclude(volume)) return showStatus(`${volume.name}: this volume includes another file; add geometries to a volume of its own`, "error");
    const geometries = Array.isArray(volume.geometries) ? volume.geometries : (volume.geometries = []);
    geometries.push(newGeometry(geometries.length + 1));
    this.#added(`${volumePath}.geometries[${geometries.length - 1}]`);
  }

  addPoseSet() {
    if (!this.#needDoc()) return;
    const geometryPath = enclosing(this.selected, "geometry");
    if (!geometryPath) return showStatus("select a geometry first: pose sets live in a geometry", "error");
    const geometry = getAt(this.doc, geometryPath);
    const sets = Array.isArray(geometry.poses_sets) ? geometry.poses_sets : (geometry.poses_sets = []);
    sets.push(newPoseSet());
    this.#added(`${geometryPath}.poses_sets[${sets.length - 1}]`);
  }

  removeSelected() {
    if (!this.#needDoc()) return;
    const parts = parsePath(this.selected);
    if (parts.length < 3) return showStatus("select a volume, geometry or pose set to remove", "error");
    const list = getAt(this.doc, formatPath(parts.slice(0, -1)));
    const removed = list[parts[parts.length - 1]];
    list.splice(parts[parts.length - 1], 1);
    this.selected = parts.length > 3 ? formatPath(parts.slice(0, -2)) : ROOT;
    this.#renderAll();
    this.#publish();
    this.check.schedule();
    showStatus(`removed ${removed && removed.name ? removed.name : "the pose set"}`);
  }

  #added(path) {
    this.selected = path;
    this.#renderAll();
    this.#publish();
    this.check.schedule();
    this.form.element.querySelector("input, select, textarea")?.focus();
  }

  #needDoc() {
    if (this.doc) return true;
    showStatus("open a world or start a new one first", "error");
    return false;
  }

  /** Select the tree item that holds `path` and put the focus on the field nearest to it. */
  selectPath(path) {
    if (!this.doc) return;
    const item = nearestPath(this.tree.paths(), path) || ROOT;
    if (item !== this.selected) {
      this.selected = item;
      this.tree.select(item);
      this.#renderForm();
    }
    this.view.highlight(item === ROOT ? null : item);
    const fields = [...this.form.element.querySelectorAll("[data-path]")].filter((e) => e.dataset.testid !== "field-error");
    const nearest = nearestPath(fields.map((e) => e.dataset.path), path);
    const target = fields.find((e) => e.dataset.path === nearest);
    const focusable = target && (target.matches("input, select, textarea") ? target : target.querySelector("input, select, textarea"));
    if (focusable && path !== item) focusable.focus();
  }

  // --- showing -----------------------------------------------------------------------------------------------------

  #renderAll() {
    this.#renderTree();
    this.#renderForm();
    this.#renderDiagnostics();
  }

  #renderTree() {
    if (!this.doc) {
      this.tree.render([], null);
      return;
    }
    const scenario = this.doc.scenario || {};
    const volumes = Array.isArray(scenario.volumes) ? scenario.volumes : [];
    const node = {
      path: ROOT, label: "Scenario", kind: "scenario",
      detail: Array.isArray(scenario.world_boundaries) ? "boundaries" : "",
      children: volumes.map((volume, v) => {
        const volumePath = `${ROOT}.volumes[${v}]`;
        const include = isInclude(volume);
        return {
          path: volumePath, kind: "volume", label: String(volume?.name ?? `volume ${v}`),
          detail: include ? `includes ${volume.world}/${volume.subworld}` : "volume",
          children: include ? [] : (Array.isArray(volume?.geometries) ? volume.geometries : []).map((geometry, g) => {
            const geometryPath = `${volumePath}.geometries[${g}]`;
            return {
              path: geometryPath, kind: "geometry", label: String(geometry?.name ?? `geometry ${g}`),
              detail: String(geometry?.shape ?? ""),
              children: (Array.isArray(geometry?.poses_sets) ? geometry.poses_sets : []).map((set, s) => ({
                path: `${geometryPath}.poses_sets[${s}]`, kind: "pose-set",
                label: `${set?.type ?? "pose set"} ${s}`, detail: String(set?.use ?? ""),
              })),
            };
          }),
        };
      }),
    };
    this.tree.render([node], this.selected);
    if (!this.tree.paths().includes(this.selected)) this.selected = ROOT;
    this.tree.select(this.selected);
    this.#renderBadges();
  }

  #renderForm() {
    if (!this.doc) {
      this.form.clear("Open a world (a name such as Gym/Four_Cylinders, or a file) or start a new one.");
      return;
    }
    const focusedPath = document.activeElement?.dataset?.path;
    const focusedInForm = this.form.element.contains(document.activeElement);
    this.form.clear();
    const path = this.selected;
    const part = getAt(this.doc, path) || {};
    const kind = partKind(path);
    const title = { scenario: "Scenario", volume: "Volume", geometry: "Geometry", poseSet: "Pose set" }[kind] || "Part";
    const section = this.form.section(`${title}${part.name ? `: ${part.name}` : ""}`);
    section.append(objectErrorsRow(path));
    if (kind === "scenario") section.append(objectErrorsRow(""));
    const fields = {
      scenario: () => scenarioFields(path),
      volume: () => volumeFields(path, part),
      geometry: () => geometryFields(path, part),
      poseSet: () => poseSetFields(path, part),
    }[kind]?.() || [];
    for (const spec of fields) this.form.field(section, spec);
    this.#otherKeys(section, path, part, fields);
    if (kind === "scenario" && !(part.volumes || []).length) {
      this.form.note(section, "No volumes yet: “+ Volume” adds one.");
    }
    if (focusedInForm && focusedPath !== undefined) {
      this.form.element.querySelector(`[data-path="${CSS.escape(focusedPath)}"]`)?.focus();
    }
    this.view.highlight(path === ROOT ? null : path);
    showFieldErrors(this.form.element, this.#diagnosticsOfSelected());
  }

  /** Keys the form does not know (a newer format, extra notes) are still shown and editable, as JSON. */
  #otherKeys(section, path, part, fields) {
    const shown = new Set(fields.map((spec) => parsePath(spec.path).pop()));
    const children = new Set(["volumes", "geometries", "poses_sets"]);
    for (const key of Object.keys(part)) {
      if (shown.has(key) || children.has(key)) continue;
      this.form.field(section, { path: childPath(path, key), label: key, kind: "json", optional: true, doc: "a key this form does not know" });
    }
  }

  #showCheck(answer) {
    this.diagnostics = Array.isArray(answer.diagnostics) ? answer.diagnostics : [];
    const viewElement = byTestId("world-view");
    if (answer.scene) {
      this.scene = answer.scene;
      this.view.setScene(answer.scene);
      delete viewElement.dataset.stale;
    } else if (this.doc) {
      viewElement.dataset.stale = "true"; // the last scene that could be laid out stays until the errors are fixed
    }
    this.#renderDiagnostics();
  }

  #renderDiagnostics() {
    renderDiagnosticsList(byTestId("world-diagnostics"), this.doc ? this.diagnostics : [], (path) => this.selectPath(path));
    this.#renderBadges();
    showFieldErrors(this.form.element, this.#diagnosticsOfSelected());
  }

  #renderBadges() {
    this.tree.setBadges(countByItem(this.tree.paths(), this.diagnostics.map((d) => ({ ...d, path: this.#itemOf(d.path) }))));
  }

  /** The tree item a diagnostic belongs to: the nearest part, the scenario for the whole file. */
  #itemOf(path) {
    return nearestPath(this.tree.paths(), path || "") || ROOT;
  }

  #diagnosticsOfSelected() {
    return this.diagnostics.filter((d) => this.#itemOf(d.path) === this.selected);
  }

  #renderChanges(changes) {
    const list = byTestId("world-changes");
    list.replaceChildren();
    if (!changes.length) {
      const none = document.createElement("li");
      none.className = "none";
      none.textContent = this.doc ? "Current format: nothing migrated." : "";
      list.append(none);
      return;
    }
    for (const change of changes) {
      const item = document.createElement("li");
      item.dataset.testid = "change";
      item.textContent = change;
      list.append(item);
    }
  }
}
