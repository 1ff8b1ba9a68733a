// The Mission view: open or create a mission, edit its agents and its states (tree + form: parameters from
// /api/mission/state_types, transitions as outcome -> target selects), see the state machine drawn by the
// server, and check it live against the world open in the World view (its poses are offered in pose fields).

import * as api from "./api.js";
import { byTestId } from "./dom.js";
import { countByItem, renderDiagnosticsList, showFieldErrors, summarise } from "./diagnostics.js";
import { setUpFilePicker } from "./file_picker.js";
import { BoundForm, objectErrorsRow } from "./form.js";
import { childPath, formatPath, getAt, nearestPath, parsePath } from "./json_path.js";
import { LiveCheck } from "./live_check.js";
import { MissionGraph } from "./mission_graph.js";
import {
  agentIds, CHILD_TERMINATION_CALLBACKS, CONTAINER_TYPES, IDS_VARS, isContainer, labelsOf, MISSION_OUTCOMES, MODELS,
  MODES, newAgent, newContainer, newState, OUTCOME_CALLBACKS, ACTION_OUTCOMES, CALLBACK_OUTCOMES, outcomesOf,
  readStateTypes,
} from "./mission_schema.js";
import { defaultSavePath, saveFromToolbar } from "./save.js";
import { session } from "./session.js";
import { showError, showStatus } from "./status.js";
import { Tree } from "./tree.js";

const ROOT = ""; // the tree's root item: the mission itself (agents and top-level keys)
const STATES = "State_Machine";

/** Keys of a state the form lays out itself (the rest are shown as JSON). */
const NODE_KEYS = new Set(["type", "name", "state_type", "parameters", "outcomes", "ids", "ids_var", "occurrencies",
  "occurrencies_outcome_map", "outcome_cb", "child_termination_cb", "connector_outcome"]);
const AGENT_KEYS = ["ID", "model", "mode", "marker_color", "ual_use", "agent_manager_on_gs"];

const MAX_CELLS_OFFERED = 200; // per geometry: a select of thousands of cells helps nobody; type the rest

/**
 * The pose definitions a world offers, from mission/check's pose_choices (one entry per volume and geometry:
 * {volume, geometry, kinds, matrix_cells, paths, pose_sets, examples}) -> [{label, group, definition}].
 * A plain definition list, or {label, definition}, is read too.
 */
export function poseDefinitions(choices) {
  const out = [];
  for (const choice of Array.isArray(choices) ? choices : []) {
    if (Array.isArray(choice)) {
      out.push({ label: JSON.stringify(choice), group: "", definition: choice });
      continue;
    }
    if (!choice || typeof choice !== "object") continue;
    if (choice.definition) {
      out.push({ label: choice.label ?? JSON.stringify(choice.definition), group: "", definition: choice.definition });
      continue;
    }
    const { volume, geometry } = choice;
    const group = geometry === "volume" ? `${volume} (its frame)` : `${volume} / ${geometry}`;
    const add = (kind, arg, label) => out.push({ label, group, definition: [volume, geometry, kind, arg] });
    (choice.matrix_cells || []).slice(0, MAX_CELLS_OFFERED).forEach((cell) => add("matrix", cell, `matrix [${cell.join(", ")}]`));
    (choice.paths || []).forEach((name) => add("path", name, `path ${name}`));
    for (let i = 0; i < (choice.pose_sets || 0); i++) add("poses", i, `every pose of set ${i}`);
    for (const example of choice.examples || []) {
      const kind = example[2];
      if (["matrix", "path", "poses"].includes(kind) && out.some((o) => o.group === group && o.definition[2] === kind)) continue;
      add(kind, example[3], `${kind} ${JSON.stringify(example[3])}`);
    }
  }
  return out;
}

export class MissionEditor {
  constructor() {
    this.doc = null;
    this.path = null;
    this.name = null;
    this.selected = ROOT;
    this.diagnostics = [];
    this.states = []; // [{path, type, json_path}] of the last check
    this.poseChoices = [];
    this.stateTypes = { types: new Map(), containers: [...CONTAINER_TYPES], containerDocs: {}, missionOutcomes: MISSION_OUTCOMES };
    this.worldDirty = false;
    this.visible = false;
    this.extraOutcomes = new Map(); // state path -> outcomes the user added to a container, not yet given a target
    this.tree = new Tree(byTestId("mission-tree"), (path) => this.selectPath(path));
    this.form = new BoundForm(byTestId("mission-form"), () => this.doc, (path, how) => this.#edited(path, how));
    this.graph = new MissionGraph(byTestId("mission-graph"), { onSelectState: (statePath) => this.#selectState(statePath) });
    this.check = new LiveCheck(
      () => api.checkMission(this.doc, this.#source(), this.#world()),
      (answer) => this.#showCheck(answer),
      (error) => showError(error, "check failed"),
    );
    this.graphSvg = null; // the last picture of the machine (the Run view lights its states)
    const files = setUpFilePicker(byTestId("mission-spec"), byTestId("mission-open"), "mission", (spec) => this.open(spec));
    byTestId("mission-new").addEventListener("click", () => this.create());
    byTestId("mission-save").addEventListener("click", () => this.save());
    byTestId("mission-save-path").addEventListener("keydown", (event) => {
      if (event.key === "Enter") this.save();
    });
    byTestId("mission-graph-fit").addEventListener("click", () => this.graph.fit());
    byTestId("mission-add-state").addEventListener("click", () => this.addState());
    byTestId("mission-add-container").addEventListener("click", () => this.addContainer());
    byTestId("mission-remove").addEventListener("click", () => this.removeSelected());
    byTestId("mission-move-up").addEventListener("click", () => this.moveSelected(-1));
    byTestId("mission-move-down").addEventListener("click", () => this.moveSelected(1));
    byTestId("mission-new-state-name").addEventListener("keydown", (event) => {
      if (event.key === "Enter") this.addState();
    });
    session.addEventListener("world", () => this.#worldChanged());
    this.#fillContainerTypes();
    /** Resolves when the file list and the state types have been asked for. */
    this.ready = Promise.all([files, this.#loadStateTypes()]);
    this.#showWorld();
    this.#renderAll();
  }

  /** The tab was shown: a world edited meanwhile means a new check (its poses and places). */
  onShow() {
    this.visible = true;
    if (this.worldDirty && this.doc) {
      this.worldDirty = false;
      this.check.now();
    }
  }

  onHide() {
    this.visible = false;
  }

  // --- documents -------------------------------------------------------------------------------------------------

  async open(spec) {
    showStatus(`opening mission ${spec}…`);
    try {
      const answer = await api.openMission(spec);
      this.#load(answer.data, answer.path || null, answer.name || spec, answer.schema || "current", answer.changes || []);
      this.#showCheck(answer);
      showStatus(`mission ${answer.name || spec} opened (${summarise(answer.diagnostics || [])})`, "ok");
      await this.check.now(); // with the world: places checked, poses offered, the states' paths
    } catch (error) {
      showError(error, `cannot open mission ${spec}`);
    }
  }

  async create() {
    try {
      const answer = await api.newMission();
      this.#load(answer.data, null, null, "current", []);
      showStatus("new mission: add states with “+ State”, connect them in each state's transitions, then save it", "ok");
      await this.check.now();
    } catch (error) {
      showError(error, "cannot start a new mission");
    }
  }

  async save() {
    const saved = await saveFromToolbar("mission", api.saveMission, this.doc);
    if (saved === null) return;
    this.path = saved;
    this.#publish();
  }

  #load(data, path, name, schema, changes) {
    this.check.cancel();
    this.doc = data;
    this.path = path;
    this.name = name;
    this.selected = ROOT;
    this.diagnostics = [];
    this.states = [];
    this.worldDirty = false;
    byTestId("mission-title").textContent = name || path || "new mission";
    byTestId("mission-save-path").value = defaultSavePath(path);
    byTestId("mission-saved").textContent = "";
    this.#renderChanges(schema, changes);
    this.graphSvg = null;
    this.graph.clear("Drawing the state machine…");
    this.#renderAll();
    this.#publish();
  }

  #publish() {
    session.setMission(this.doc ? { data: this.doc, path: this.path, name: this.name, source: this.#source() } : null);
  }

  #source() {
    return this.path || this.name || "new mission";
  }

  /** The world open in the World view, as mission/check takes it. */
  #world() {
    const world = session.world;
    return world && world.data ? { data: world.data, source: world.source || world.path || world.name || "world" } : null;
  }

  #worldChanged() {
    this.#showWorld();
    if (!this.doc) return;
    if (this.visible) this.check.schedule();
    else this.worldDirty = true;
  }

  #showWorld() {
    const world = session.world;
    const label = byTestId("mission-world");
    label.textContent = world ? `in world ${world.name || world.path || "(new world)"}` : "no world open: places not checked";
    label.classList.toggle("missing", !world);
  }

  async #loadStateTypes() {
    try {
      this.stateTypes = readStateTypes(await api.stateTypes());
    } catch (error) {
      showError(error, "cannot read the state types");
    }
    const select = byTestId("mission-new-state-type");
    select.replaceChildren();
    for (const [name, info] of this.stateTypes.types) {
      const option = document.createElement("option");
      option.value = name;
      option.textContent = name;
      option.title = info.doc || info.nodeTypes.join(" or ");
      select.append(option);
    }
    this.#fillContainerTypes();
    if (this.doc) this.#renderForm();
  }

  #fillContainerTypes() {
    const select = byTestId("mission-new-container-type");
    select.replaceChildren();
    for (const name of this.stateTypes.containers) {
      const option = document.createElement("option");
      option.value = name;
      option.textContent = name;
      select.append(option);
    }
  }

  // --- editing -----------------------------------------------------------------------------------------------------

  #edited(path, { structural }) {
    if (structural) this.#applyDefaults(path);
    const labelChanged = /\.(name|type|state_type|ids|ids_var)$/.test(path) || /^(Agents_Config|UAVs_Config)\[\d+\]\.ID$/.test(path);
    if (structural) this.#renderForm();
    if (structural || labelChanged) this.#renderTree();
    this.#publish();
    this.check.schedule();
  }

  /** A new state type: the parameters of the new one (same-named values kept); a new node type: its keys. */
  #applyDefaults(path) {
    const nodePath = formatPath(parsePath(path).slice(0, -1));
    const node = getAt(this.doc, nodePath);
    if (!node || typeof node !== "object") return;
    if (path.endsWith(".state_type")) {
      const info = this.stateTypes.types.get(node.state_type);
      const fresh = newState(node.state_type, node.name, info, this.#parentOf(nodePath), this.doc).parameters;
      const old = node.parameters && typeof node.parameters === "object" ? node.parameters : {};
      node.parameters = Object.fromEntries(Object.entries(fresh).map(([k, v]) => [k, k in old ? old[k] : v]));
      if (info && !info.nodeTypes.includes(node.type)) node.type = info.nodeTypes[0];
    } else if (path.endsWith(".type") && isContainer(node)) {
      const template = newContainer(node.type, node.name, this.#parentOf(nodePath));
      for (const key of ["outcome_cb", "child_termination_cb", "occurrencies_outcome_map", "connector_outcome"]) {
        if (key in template && !(key in node)) node[key] = template[key];
      }
      if (!Array.isArray(node.occurrencies)) node.occurrencies = [];
    }
  }

  /** The container node that holds the node at `nodePath`, or null at the top level. */
  #parentOf(nodePath) {
    const parts = parsePath(nodePath);
    return parts.length > 2 ? getAt(this.doc, formatPath(parts.slice(0, -2))) : null;
  }

  /** Where a new node goes: into the selected container, after the selected state, or at the end. */
  #insertionPoint() {
    const selected = this.selected === ROOT ? null : getAt(this.doc, this.selected);
    if (selected && isContainer(selected)) {
      if (!Array.isArray(selected.occurrencies)) selected.occurrencies = [];
      return { list: selected.occurrencies, index: selected.occurrencies.length, listPath: `${this.selected}.occurrencies`, parent: selected };
    }
    if (selected) {
      const parts = parsePath(this.selected);
      const listPath = formatPath(parts.slice(0, -1));
      return { list: getAt(this.doc, listPath), index: parts[parts.length - 1] + 1, listPath, parent: this.#parentOf(this.selected) };
    }
    if (!Array.isArray(this.doc[STATES])) this.doc[STATES] = [];
    return { list: this.doc[STATES], index: this.doc[STATES].length, listPath: STATES, parent: null };
  }

  #newName(base) {
    const input = byTestId("mission-new-state-name");
    const typed = input.value.trim();
    input.value = "";
    if (typed) return typed;
    const taken = new Set();
    const walk = (nodes) => (Array.isArray(nodes) ? nodes : []).forEach((n) => { taken.add(n?.name); walk(n?.occurrencies); });
    walk(this.doc[STATES]);
    let n = 1;
    while (taken.has(`${base}_${n}`)) n++;
    return `${base}_${n}`;
  }

  addState() {
    if (!this.#needDoc()) return;
    const type = byTestId("mission-new-state-type").value;
    if (!type) return showStatus("no state types known: is magna studio's server running?", "error");
    const where = this.#insertionPoint();
    const node = newState(type, this.#newName(type), this.stateTypes.types.get(type), where.parent, this.doc);
    where.list.splice(where.index, 0, node);
    this.#added(`${where.listPath}[${where.index}]`, `added ${node.type} ${node.name}`);
  }

  addContainer() {
    if (!this.#needDoc()) return;
    const type = byTestId("mission-new-container-type").value || "Concurrence";
    const where = this.#insertionPoint();
    const node = newContainer(type, this.#newName(type.toLowerCase()), where.parent);
    where.list.splice(where.index, 0, node);
    this.#added(`${where.listPath}[${where.index}]`, `added ${type} ${node.name}: add its states with it selected`);
  }

  removeSelected() {
    if (!this.#needDoc()) return;
    if (this.selected === ROOT) return showStatus("select a state or container to remove", "error");
    const parts = parsePath(this.selected);
    const list = getAt(this.doc, formatPath(parts.slice(0, -1)));
    const [removed] = list.splice(parts[parts.length - 1], 1);
    this.selected = parts.length > 2 ? formatPath(parts.slice(0, -2)) : ROOT;
    this.#changedStructure();
    showStatus(`removed ${removed?.name ?? "the state"}; transitions that led to it are now listed as problems`);
  }

  /** Move the selected state up (-1) or down (+1) among its siblings (the first one of a list starts it). */
  moveSelected(step) {
    if (!this.#needDoc() || this.selected === ROOT) return;
    const parts = parsePath(this.selected);
    const index = parts[parts.length - 1];
    const list = getAt(this.doc, formatPath(parts.slice(0, -1)));
    const target = index + step;
    if (target < 0 || target >= list.length) return;
    [list[index], list[target]] = [list[target], list[index]];
    this.selected = formatPath([...parts.slice(0, -1), target]);
    this.#changedStructure();
  }

  addAgent() {
    if (!this.#needDoc()) return;
    const key = this.#agentsKey();
    if (!Array.isArray(this.doc[key])) this.doc[key] = [];
    this.doc[key].push(newAgent(this.doc));
    this.#changedStructure();
  }

  removeAgent(index) {
    this.doc[this.#agentsKey()].splice(index, 1);
    this.#changedStructure();
  }

  #agentsKey() {
    return !("Agents_Config" in this.doc) && "UAVs_Config" in this.doc ? "UAVs_Config" : "Agents_Config";
  }

  #added(path, message) {
    this.selected = path;
    this.#changedStructure();
    showStatus(message);
    this.form.element.querySelector("input, select, textarea")?.focus();
  }

  #changedStructure() {
    this.#renderAll();
    this.#publish();
    this.check.schedule();
  }

  #needDoc() {
    if (this.doc) return true;
    showStatus("open a mission or start a new one first", "error");
    return false;
  }

  /** Select the tree item holding `path` and focus the field nearest to it. */
  selectPath(path) {
    if (!this.doc) return;
    const item = nearestPath(this.tree.paths(), path) ?? ROOT;
    if (item !== this.selected) {
      this.selected = item;
      this.tree.select(item);
      this.#renderForm();
    }
    const fields = [...this.form.element.querySelectorAll("[data-path]")].filter((e) => e.dataset.testid !== "field-error");
    const nearest = nearestPath(fields.map((e) => e.dataset.path), path);
    const target = fields.find((e) => e.dataset.path === nearest);
    const focusable = target && (target.matches("input, select, textarea") ? target : target.querySelector("input, select, textarea"));
    if (focusable && path !== item) focusable.focus();
  }

  /** A state clicked in the graph: select the node of the file it comes from. */
  #selectState(statePath) {
    const state = this.states.find((s) => s.path === statePath);
    if (state && state.json_path !== undefined) this.selectPath(state.json_path === STATES ? ROOT : state.json_path);
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
    const nodeOf = (node, path) => {
      const kind = isContainer(node) ? "container" : node?.type === "CBState" ? "callback" : "action";
      const ids = node?.ids === undefined ? "" : ` ×${Array.isArray(node.ids) ? node.ids.join(",") : node.ids}`;
      return {
        path, kind, label: String(node?.name ?? "(no name)"),
        detail: (isContainer(node) ? node.type : String(node?.state_type ?? node?.type ?? "")) + ids,
        children: isContainer(node) && Array.isArray(node.occurrencies)
          ? node.occurrencies.map((child, i) => nodeOf(child, `${path}.occurrencies[${i}]`)) : [],
      };
    };
    const agents = agentIds(this.doc);
    const root = {
      path: ROOT, kind: "mission", label: "Mission",
      detail: `${agents.length} agent${agents.length === 1 ? "" : "s"}`,
      children: (Array.isArray(this.doc[STATES]) ? this.doc[STATES] : []).map((node, i) => nodeOf(node, `${STATES}[${i}]`)),
    };
    this.tree.render([root], this.selected);
    if (!this.tree.paths().includes(this.selected)) this.selected = ROOT;
    this.tree.select(this.selected);
    this.#renderBadges();
  }

  #renderForm() {
    if (!this.doc) {
      this.form.clear("Open a mission (a name such as Gym/All_Take_Off, or a file) or start a new one.");
      this.graph.markSelected([]);
      return;
    }
    const focusedPath = document.activeElement?.dataset?.path;
    const focusedInForm = this.form.element.contains(document.activeElement);
    this.form.clear();
    if (this.selected === ROOT) this.#missionForm();
    else this.#stateForm(this.selected, getAt(this.doc, this.selected) || {});
    if (focusedInForm && focusedPath !== undefined) {
      this.form.element.querySelector(`[data-path="${CSS.escape(focusedPath)}"]`)?.focus();
    }
    this.graph.markSelected(this.states.filter((s) => s.json_path === this.selected).map((s) => s.path), { reveal: true });
    showFieldErrors(this.form.element, this.#diagnosticsOfSelected());
  }

  /** The mission itself: its agents and its other top-level keys. */
  #missionForm() {
    const key = this.#agentsKey();
    this.form.element.append(objectErrorsRow(ROOT), objectErrorsRow(key));
    const agents = Array.isArray(this.doc[key]) ? this.doc[key] : [];
    agents.forEach((agent, i) => {
      const base = `${key}[${i}]`;
      const section = this.form.section(`Agent ${agent?.ID ?? i}`);
      section.append(objectErrorsRow(base));
      this.form.field(section, { path: `${base}.ID`, label: "ID", kind: "number" });
      this.form.field(section, { path: `${base}.model`, label: "model", kind: "choice", choices: MODELS });
      this.form.field(section, { path: `${base}.mode`, label: "mode", kind: "choice", choices: MODES,
        doc: "sitl: simulated; hil: hardware in the loop; real: a real flight" });
      this.form.field(section, { path: `${base}.marker_color`, label: "marker_color", kind: "vector", size: 4,
        axes: ["r", "g", "b", "alpha"], doc: "r, g, b (0-255) and alpha (0-1)" });
      this.form.field(section, { path: `${base}.ual_use`, label: "ual_use", kind: "bool", optional: true });
      this.form.field(section, { path: `${base}.agent_manager_on_gs`, label: "agent_manager_on_gs", kind: "bool", optional: true });
      for (const other of Object.keys(agent || {}).filter((k) => !AGENT_KEYS.includes(k))) {
        this.form.field(section, { path: childPath(base, other), label: other, kind: "json", optional: true });
      }
      const remove = button(`Remove agent ${agent?.ID ?? i}`, () => this.removeAgent(i));
      remove.dataset.testid = "mission-remove-agent";
      section.append(remove);
    });
    const add = button("+ Agent", () => this.addAgent());
    add.dataset.testid = "mission-add-agent";
    this.form.element.append(add);
    const others = Object.keys(this.doc).filter((k) => ![key, STATES].includes(k));
    if (others.length) {
      const section = this.form.section("Other keys");
      for (const other of others) this.form.field(section, { path: other, label: other, kind: "json", optional: true });
    }
    if (!(this.doc[STATES] || []).length) {
      this.form.note(this.form.element, "No states yet: choose a state type and “+ State”. The first state of a list starts it.");
    }
  }

  #stateForm(base, node) {
    const container = isContainer(node);
    const parent = this.#parentOf(base);
    const section = this.form.section(`${container ? node.type : node.state_type ?? "State"}: ${node.name ?? ""}`);
    section.append(objectErrorsRow(base));
    this.form.field(section, { path: `${base}.name`, label: "name", kind: "text",
      doc: node.type === "CBState" ? "transitions name it so" : "transitions name it {id}_{name}, one state per id" });
    if (container) {
      this.form.field(section, { path: `${base}.type`, label: "type", kind: "choice", choices: this.stateTypes.containers, structural: true });
    } else {
      const info = this.stateTypes.types.get(node.state_type);
      this.form.field(section, { path: `${base}.state_type`, label: "state_type", kind: "choice",
        choices: [...this.stateTypes.types.keys()], structural: true, doc: info?.doc });
      this.form.field(section, { path: `${base}.type`, label: "type", kind: "choice", structural: true,
        choices: info ? info.nodeTypes : ["CBState", "SimpleActionState"],
        doc: "CBState: done by the ground station; SimpleActionState: a goal to a UAV" });
    }
    this.form.field(section, { path: `${base}.ids`, label: "ids", kind: "ids", optional: true,
      doc: "an id, a list of ids (1, 2), or all" });
    this.form.field(section, { path: `${base}.ids_var`, label: "ids_var", kind: "choice", choices: IDS_VARS, optional: true,
      doc: "agent: one state per agent; wp: one per waypoint of the path" });

    if (container) this.#containerFields(base, node);
    else this.#parameterFields(base, node);
    // a Concurrence's children have no transitions; one written anyway is shown so that it can be removed
    const written = node.outcomes && typeof node.outcomes === "object" && Object.keys(node.outcomes).length;
    if (!(parent && parent.type === "Concurrence") || written) this.#transitionFields(base, node, parent);

    const extra = Object.keys(node).filter((k) => !NODE_KEYS.has(k));
    if (extra.length) {
      const other = this.form.section("Other keys");
      for (const key of extra) this.form.field(other, { path: childPath(base, key), label: key, kind: "json", optional: true });
    }
  }

  #containerFields(base, node) {
    const section = this.form.section(node.type);
    if (node.type === "Concurrence") {
      this.form.field(section, { path: `${base}.outcome_cb`, label: "outcome_cb", kind: "choice", choices: OUTCOME_CALLBACKS, optional: true,
        doc: "decides the outcome before the map (collision when any child collided)" });
      this.form.field(section, { path: `${base}.child_termination_cb`, label: "child_termination_cb", kind: "choice",
        choices: CHILD_TERMINATION_CALLBACKS, optional: true, doc: "stops the other children early" });
      this.form.field(section, { path: `${base}.occurrencies_outcome_map`, label: "occurrencies_outcome_map", kind: "json",
        optional: true, doc: "{outcome: {child label or \"all\": child outcome}}" });
    } else if (node.type === "Sequence") {
      this.form.field(section, { path: `${base}.connector_outcome`, label: "connector_outcome", kind: "choice",
        choices: [...ACTION_OUTCOMES, ...CALLBACK_OUTCOMES], doc: "the outcome that goes on to the next state" });
    }
    const count = Array.isArray(node.occurrencies) ? node.occurrencies.length : 0;
    this.form.note(section, count ? `${count} state${count === 1 ? "" : "s"} inside (in the tree).`
      : "Empty: with it selected, “+ State” adds a state into it.");
  }

  #parameterFields(base, node) {
    const info = this.stateTypes.types.get(node.state_type);
    const section = this.form.section("Parameters");
    section.append(objectErrorsRow(`${base}.parameters`));
    const params = node.parameters && typeof node.parameters === "object" ? node.parameters : {};
    const described = info ? info.parameters : [];
    for (const p of described) this.form.field(section, this.#parameterSpec(`${base}.parameters`, p));
    const known = new Set(described.map((p) => p.name));
    for (const key of Object.keys(params).filter((k) => !known.has(k))) {
      this.form.field(section, { path: `${base}.parameters.${key}`, label: key, kind: "json", optional: true,
        doc: info ? "not a parameter of this state type" : "" });
    }
    if (!described.length && !Object.keys(params).length) this.form.note(section, "This state type takes no parameters.");
  }

  /** A parameter of state_types -> a form field (pose fields and lists of poses offer the world's poses). */
  #parameterSpec(base, p) {
    const spec = { path: `${base}.${p.name}`, label: p.name, optional: !p.required, doc: p.doc || "" };
    const poses = poseDefinitions(this.poseChoices);
    const alternatives = (Array.isArray(p.also) ? p.also : []).map((value) => ({
      label: `set to ${JSON.stringify(value)}`, apply: () => value,
    }));
    const withChoices = (choices, label) => {
      const all = [...alternatives, ...choices];
      return all.length ? { ...spec, kind: "json", append: { label, choices: all } } : { ...spec, kind: "json" };
    };
    switch (p.kind) {
      case "number": return { ...spec, kind: "number" };
      case "bool": return { ...spec, kind: "bool" };
      case "choice": return { ...spec, kind: "choice", choices: Array.isArray(p.choices) ? p.choices : [] };
      case "uav": return { ...spec, kind: "choice", choices: agentIds(this.doc) };
      case "text": return { ...spec, kind: "text" };
      case "pose":
        return withChoices(poses.map((pose) => ({ ...pose, apply: () => structuredClone(pose.definition) })),
          poses.length ? "set a pose of the world…" : "(open a world for its poses)");
      case "list":
        if (p.items === "number" && Number.isInteger(p.length)) return { ...spec, kind: "vector", size: p.length };
        if (p.items === "pose") {
          const wrap = (definition) => (p.item_key ? { [p.item_key]: structuredClone(definition) }
            : p.yaw ? [...structuredClone(definition), 0] : structuredClone(definition));
          return withChoices(poses.map((pose) => ({
            ...pose, apply: (current) => [...(Array.isArray(current) ? current : []), wrap(pose.definition)],
          })), poses.length ? "add a pose of the world…" : "(open a world for its poses)");
        }
        return withChoices([], "");
      default: return withChoices([], "");
    }
  }

  /** One select per outcome: the sibling state it leads to, or an outcome of the enclosing container. */
  #transitionFields(base, node, parent) {
    const section = this.form.section("Transitions");
    section.append(objectErrorsRow(`${base}.outcomes`));
    const parts = parsePath(base);
    const siblings = getAt(this.doc, formatPath(parts.slice(0, -1))) || [];
    const targets = [];
    for (const sibling of siblings) {
      for (const label of this.#labels(sibling, siblings.indexOf(sibling), parts)) targets.push({ value: label, label });
    }
    const ends = parent ? Object.keys(parent.outcomes || {}) : this.stateTypes.missionOutcomes || MISSION_OUTCOMES;
    const endLabel = parent ? "ends the container with" : "ends the mission with";
    for (const end of ends) targets.push({ value: end, label: `${endLabel} ${end}` });
    for (const outcome of new Set([...outcomesOf(node), ...(this.extraOutcomes.get(base) || [])])) {
      this.form.field(section, { path: `${base}.outcomes.${outcome}`, label: outcome, kind: "choice", choices: targets, optional: true });
    }
    if (isContainer(node)) {
      const row = document.createElement("div");
      row.className = "inline-add";
      const input = document.createElement("input");
      input.type = "text";
      input.placeholder = "another outcome";
      input.setAttribute("aria-label", "another outcome of this container");
      input.dataset.testid = "mission-new-outcome";
      const add = button("+ Outcome", () => {
        const name = input.value.trim();
        if (!name) return input.focus();
        // offered until a target is chosen: an outcome without a target is not written to the file
        this.extraOutcomes.set(base, [...(this.extraOutcomes.get(base) || []), name]);
        this.#renderForm();
        this.form.element.querySelector(`[data-path="${CSS.escape(`${base}.outcomes.${name}`)}"]`)?.focus();
      });
      add.dataset.testid = "mission-add-outcome";
      row.append(input, add);
      section.append(row);
    }
  }

  /** The labels of a sibling: from the last check's states when it has them, else from its ids. */
  #labels(sibling, index, parts) {
    const jsonPath = formatPath([...parts.slice(0, -1), index]);
    const fromCheck = [...new Set(this.states.filter((s) => s.json_path === jsonPath).map((s) => String(s.path).split("/").pop()))];
    return fromCheck.length ? fromCheck : labelsOf(sibling, this.doc);
  }

  #showCheck(answer) {
    this.diagnostics = Array.isArray(answer.diagnostics) ? answer.diagnostics : [];
    if (Array.isArray(answer.states)) this.states = answer.states;
    const choicesChanged = Array.isArray(answer.pose_choices)
      && JSON.stringify(answer.pose_choices) !== JSON.stringify(this.poseChoices);
    if (Array.isArray(answer.pose_choices)) this.poseChoices = answer.pose_choices;
    if ("graph_svg" in answer) {
      this.graphSvg = answer.graph_svg || null;
      this.graph.setSvg(answer.graph_svg);
    }
    const focusInForm = this.form.element.contains(document.activeElement);
    // New pose choices or state labels change the selects; rebuild the form unless the user is typing in it.
    if (choicesChanged && !focusInForm) this.#renderForm();
    this.graph.markSelected(this.states.filter((s) => s.json_path === this.selected).map((s) => s.path));
    this.#renderDiagnostics();
  }

  #renderDiagnostics() {
    renderDiagnosticsList(byTestId("mission-diagnostics"), this.doc ? this.diagnostics : [], (path) => this.selectPath(path));
    this.#renderBadges();
    showFieldErrors(this.form.element, this.#diagnosticsOfSelected());
  }

  #renderBadges() {
    this.tree.setBadges(countByItem(this.tree.paths(), this.diagnostics.map((d) => ({ ...d, path: this.#itemOf(d.path) }))));
  }

  #itemOf(path) {
    return nearestPath(this.tree.paths(), path || "") ?? ROOT;
  }

  #diagnosticsOfSelected() {
    return this.diagnostics.filter((d) => this.#itemOf(d.path) === this.selected);
  }

  #renderChanges(schema, changes) {
    const block = byTestId("mission-changes");
    block.replaceChildren();
    const head = document.createElement("p");
    head.dataset.testid = "mission-schema";
    head.textContent = schema === "legacy" ? "Legacy schema, migrated to the current one:" : "Current schema: nothing migrated.";
    block.append(head);
    if (!changes.length) return;
    const list = document.createElement("ul");
    list.className = "changes";
    for (const change of changes) {
      const item = document.createElement("li");
      item.dataset.testid = "change";
      item.textContent = change;
      list.append(item);
    }
    block.append(list);
  }
}

function button(text, onClick) {
  const element = document.createElement("button");
  element.type = "button";
  element.textContent = text;
  element.addEventListener("click", onClick);
  return element;
}
