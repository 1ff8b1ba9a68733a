// The structure of a mission document (ROS-MAGNA's format as magna_gs reads it: DESIGN.md "File formats",
// src/magna_gs/README.md): node types, outcome vocabularies, how states are named after `ids` expansion, what a
// new state or container looks like, and the reading of /api/mission/state_types.

export const LEAF_TYPES = ["CBState", "SimpleActionState"];
export const CONTAINER_TYPES = ["StateMachine", "Concurrence", "Sequence"];
export const ACTION_OUTCOMES = ["succeeded", "collision", "low_battery", "GS_critical_event", "utm_new_flightplan",
  "preempted", "aborted"];
export const CALLBACK_OUTCOMES = ["completed", "failed"];
export const MISSION_OUTCOMES = ["completed", "failed"]; // what a top-level transition may end the mission with
export const CONTAINER_OUTCOMES = ["completed", "failed", "collision"]; // offered for a container; others can be added
export const IDS_VARS = ["agent", "wp"];
export const OUTCOME_CALLBACKS = ["collision_if_any_collided"];
export const CHILD_TERMINATION_CALLBACKS = ["all_at_one_collision"];
export const MODELS = ["iris", "typhoon_h480", "f550", "crazyflie", "plane"];
export const MODES = ["sitl", "hil", "real"];

// Which leaf type runs a state type when state_types does not say (save_csv is both: the ground station's for
// several agents, or a UAV's own).
const CALLBACK_TYPES = ["world_config", "wait", "spawn_agents", "algorithm_control", "save_csv"];

export const isContainer = (node) => Boolean(node) && CONTAINER_TYPES.includes(node.type);

/**
 * /api/mission/state_types, read defensively -> {types: Map(name -> {name, nodeTypes, parameters, outcomes, doc}),
 * containers: [name], containerDocs: {name: doc}, missionOutcomes}. The server's form:
 * {"states": {type: {"doc", "leaf_types", "outcomes": {leaf type: [...]}, "parameters": [field]}},
 *  "containers": {type: {"doc", "fields"}}, "mission_outcomes": [...]}; a list of {name, ...} is read too.
 */
export function readStateTypes(answer) {
  const source = answer && (answer.states ?? answer.state_types ?? answer.types);
  const entries = Array.isArray(source)
    ? source.map((entry) => [entry.name ?? entry.state_type ?? entry.type, entry])
    : Object.entries(source || {});
  const types = new Map();
  for (const [name, entry] of entries) {
    if (!name) continue;
    const info = Array.isArray(entry) ? { parameters: entry } : entry || {};
    let nodeTypes = info.leaf_types ?? info.node_types ?? info.node_type ?? info.kind;
    if (typeof nodeTypes === "string") nodeTypes = [nodeTypes];
    nodeTypes = (Array.isArray(nodeTypes) ? nodeTypes : []).filter((t) => LEAF_TYPES.includes(t));
    if (!nodeTypes.length) nodeTypes = CALLBACK_TYPES.includes(name) ? ["CBState"] : ["SimpleActionState"];
    types.set(name, {
      name, nodeTypes, doc: info.doc || "",
      outcomes: info.outcomes && typeof info.outcomes === "object" ? info.outcomes : {},
      parameters: (Array.isArray(info.parameters) ? info.parameters : []).filter((p) => p && p.name),
    });
  }
  const rawContainers = answer && (answer.containers ?? answer.container_types);
  const containerDocs = {};
  let containers = [];
  if (Array.isArray(rawContainers)) {
    containers = rawContainers.map((c) => (typeof c === "string" ? c : c.name || c.type)).filter(Boolean);
  } else if (rawContainers && typeof rawContainers === "object") {
    containers = Object.keys(rawContainers);
    for (const [name, info] of Object.entries(rawContainers)) containerDocs[name] = info?.doc || "";
  }
  const missionOutcomes = Array.isArray(answer?.mission_outcomes) ? answer.mission_outcomes : MISSION_OUTCOMES;
  return { types, containers: containers.length ? containers : [...CONTAINER_TYPES], containerDocs, missionOutcomes };
}

/** The agent IDs of the mission (Agents_Config, or the legacy UAVs_Config). */
export function agentIds(doc) {
  const agents = doc && (doc.Agents_Config || doc.UAVs_Config);
  return Array.isArray(agents) ? agents.map((a) => a && a.ID).filter((id) => id !== undefined && id !== null) : [];
}

/** The ids a node expands to ("all": every agent, or every waypoint with ids_var wp). */
function expandedIds(node, doc) {
  if (node.ids === undefined || node.ids === null) return [];
  if (node.ids === "all") {
    if (node.ids_var === "wp") {
      const path = node.parameters && node.parameters.path;
      return Array.isArray(path) ? path.map((_, i) => i + 1) : [];
    }
    return agentIds(doc);
  }
  return Array.isArray(node.ids) ? node.ids : [node.ids];
}

/** The labels other states' transitions use for this node: CBStates keep `name`, others are `{id}_{name}`. */
export function labelsOf(node, doc) {
  if (!node || typeof node !== "object") return [];
  const name = String(node.name ?? "");
  if (node.type === "CBState") return [name];
  const ids = expandedIds(node, doc);
  return ids.length ? ids.map((id) => `${id}_${name}`) : [name];
}

/** Outcomes a node can end with, for its transitions (those it already maps come first). */
export function outcomesOf(node) {
  const written = Object.keys((node && node.outcomes) || {});
  const vocabulary = node.type === "CBState" ? CALLBACK_OUTCOMES
    : node.type === "SimpleActionState" ? ACTION_OUTCOMES
      : CONTAINER_OUTCOMES;
  return [...new Set([...written, ...vocabulary])];
}

/**
 * What the parameters of a new state start with: each default, and an example of each parameter it needs
 * (required, or required_when the values chosen so far say so), so that a new state is close to valid.
 */
export function defaultParameters(info) {
  const parameters = {};
  const blank = (p) => (p.kind === "list" ? [] : p.kind === "bool" ? false : p.kind === "number" ? 0 : "");
  const needed = (p) => p.required || Object.entries(p.required_when || {}).some(
    ([key, values]) => Array.isArray(values) && values.includes(parameters[key]));
  for (const p of info ? info.parameters : []) {
    if (p.default !== undefined && p.default !== null) parameters[p.name] = structuredClone(p.default);
    else if (needed(p)) parameters[p.name] = structuredClone(p.example ?? blank(p));
  }
  return parameters;
}

/**
 * A new leaf state of state type `type`, named `name`, to go into `parent` (a container node, or null: the top
 * level). Its ids follow the missions' custom: every agent inside a Concurrence, the container's UAV inside a
 * container with ids_var agent, the first agent at the top level.
 */
export function newState(type, name, info, parent, doc) {
  const nodeType = info && info.nodeTypes.length ? info.nodeTypes[0] : "SimpleActionState";
  const node = { type: nodeType, state_type: type, name };
  const agents = agentIds(doc);
  const addressesAgents = nodeType === "SimpleActionState" || ["save_csv", "algorithm_control"].includes(type);
  if (addressesAgents) {
    if (parent && parent.type === "Concurrence") Object.assign(node, { ids: "all", ids_var: "agent" });
    else if (parent && parent.ids_var === "agent") { /* the container's UAV */ }
    else if (nodeType === "CBState") Object.assign(node, { ids: "all", ids_var: "agent" });
    else node.ids = agents.length ? agents[0] : 1;
  }
  node.parameters = defaultParameters(info);
  if (!(parent && parent.type === "Concurrence")) node.outcomes = {}; // a Concurrence's children have no transitions
  return node;
}

/** A new container of `type` named `name` (a Concurrence as the project's missions write theirs). */
export function newContainer(type, name, parent) {
  const node = { type, name, ids: 1, occurrencies: [] };
  if (type === "Concurrence") {
    Object.assign(node, {
      outcome_cb: "collision_if_any_collided",
      child_termination_cb: "all_at_one_collision",
      occurrencies_outcome_map: { completed: { all: "succeeded" }, failed: { all: "aborted" } },
    });
  } else if (type === "Sequence") {
    node.connector_outcome = "succeeded";
  }
  if (!(parent && parent.type === "Concurrence")) node.outcomes = {};
  return node;
}

/** A new agent entry with the next free ID. */
export function newAgent(doc) {
  const ids = agentIds(doc).filter((id) => Number.isInteger(id));
  const id = ids.length ? Math.max(...ids) + 1 : 1;
  const palette = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 200, 0], [200, 0, 255], [0, 200, 255]];
  return { ID: id, model: "iris", mode: "sitl", marker_color: [...palette[(id - 1) % palette.length], 0.5],
    ual_use: true, agent_manager_on_gs: true };
}
