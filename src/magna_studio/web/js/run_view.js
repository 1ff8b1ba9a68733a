// The Run view: start `magna run` on the world and mission the page holds, follow its progress,
// and, through the bridge node of the running simulation, watch the UAVs (positions and paths in
// the 3-D view, role, battery, UAL state), light the active states on the graph, list critical
// events, send operator commands (the ground station's command service, as voice does), pause and
// resume. After the run, link its reports.

import { BridgeClient } from "./bridge_client.js";
import { byTestId } from "./dom.js";

const STATUS_PERIOD_MS = 500;
const POSE_THROTTLE_MS = 50; // 20 Hz per UAV: the view asks for more than the 10 Hz the issue wants
const TRAIL_POINTS = 600;
const UAL_STATES = ["UNINITIALIZED", "LANDED_DISARMED", "LANDED_ARMED", "TAKING_OFF", "FLYING_AUTO",
  "FLYING_MANUAL", "LANDING"]; // uav_abstraction_layer/State constants, in their numeric order
const COMMAND = { service: "/magna/gs/command", type: "magna_msgs/GroundStationCommand" };
const ACTIONS = {
  basic_action: ["take_off", "land", "move", "turn", "follow"],
  mission: ["standby", "resume", "critical"],
  parameters: ["get"],
  algorithms: ["set"],
};

function el(root, testid) {
  return byTestId(testid, root);
}

function agentsOf(mission) {
  const agents = (mission && (mission.Agents_Config || mission.UAVs_Config)) || [];
  return agents.filter((a) => Number.isInteger(a.ID)).map((a) => ({
    id: a.ID,
    color: Array.isArray(a.marker_color) ? a.marker_color : [255, 255, 255, 1],
  }));
}

// Active states of every container, as full paths ("/MISSION/leg_1"), from SMStatus messages.
class ActiveStates {
  constructor() {
    this.byContainer = new Map();
  }

  update(status) {
    const finished = (status.info || "").startsWith("finished");
    this.byContainer.set(status.path, finished ? [] : status.active_states.map((s) => `${status.path}/${s}`));
  }

  paths() {
    const all = [];
    for (const [container, states] of this.byContainer) {
      const parentActive = container.split("/").length <= 2 || this.isActive(container);
      if (parentActive) all.push(...states);
    }
    return all;
  }

  isActive(path) {
    const parent = path.slice(0, path.lastIndexOf("/"));
    return (this.byContainer.get(parent) || []).includes(path);
  }
}

export class RunView {
  // hooks: {world(): {data, name}, mission(): {data, name}, scene(): scene|null, graphSvg(): str|null}
  // makeView(container) -> a WorldView; makeGraph(container) -> a MissionGraph (setSvg, lightStates)
  constructor(root, hooks, makeView, makeGraph, setStatus) {
    this.root = root;
    this.hooks = hooks;
    this.setStatus = setStatus;
    this.view = makeView(el(root, "run-3d"));
    this.graph = makeGraph(el(root, "run-graph"));
    this.bridge = null;
    this.bridgeUrl = null;
    this.uavs = new Map(); // id -> {position, trail, role, battery, state, updates}
    this.active = new ActiveStates();
    this.stats = { started: performance.now(), poses: 0 }; // read by bench/studio_bridge.py
    window.magnaStudioRun = this;
    el(root, "run-start").addEventListener("click", () => this.start());
    el(root, "run-stop").addEventListener("click", () => this.stop());
    el(root, "run-pause").addEventListener("click", () => this.command("mission", "standby", "all", []));
    el(root, "run-resume").addEventListener("click", () => this.command("mission", "resume", "all", []));
    el(root, "run-continue").addEventListener("click", () => this.pressContinue());
    el(root, "command-intent").addEventListener("change", () => this.fillActions());
    el(root, "command-send").addEventListener("click", () => this.sendCommandForm());
    this.fillActions();
    this.poll();
  }

  // --- the run ----------------------------------------------------------------------------------------
  async start() {
    const world = runnable(this.hooks.world(), "New_World");
    const mission = runnable(this.hooks.mission(), "New_Mission");
    if (!world || !mission) {
      this.setStatus("open or create a world and a mission first", "error");
      return;
    }
    const body = {
      world, mission,
      n_iter: Number(el(this.root, "run-n-iter").value) || 1,
      rtf: el(this.root, "run-rtf").value || "1",
      seed: Number(el(this.root, "run-seed").value) || 0,
      name: el(this.root, "run-name").value || "studio",
    };
    try {
      await this.post("/api/run/start", body);
      this.resetLive();
      this.setStatus("magna run started");
    } catch (error) {
      this.setStatus(error.message, "error");
    }
  }

  async stop() {
    try {
      await this.post("/api/run/stop", {});
      this.setStatus("magna run stopped");
    } catch (error) {
      this.setStatus(error.message, "error");
    }
  }

  async post(url, body) {
    const answer = await fetch(url, {
      method: "POST", headers: { "Content-Type": "application/json", "X-Magna-Studio": "1" },
      body: JSON.stringify(body),
    });
    const data = await answer.json();
    if (!answer.ok) throw new Error(data.error || `${url}: HTTP ${answer.status}`);
    return data;
  }

  resetLive() {
    const scene = this.hooks.scene();
    if (scene) this.view.setScene(scene);
    this.uavs.clear();
    this.active = new ActiveStates();
    this.graph.setSvg(this.hooks.graphSvg(), "The mission's graph shows once the mission checks without errors.");
    el(this.root, "run-events").replaceChildren();
    el(this.root, "uav-table").querySelector("tbody").replaceChildren();
    el(this.root, "run-reports").replaceChildren();
    for (const agent of agentsOf(this.hooks.mission()?.data)) this.uav(agent.id, agent.color);
  }

  async poll() {
    try {
      const answer = await fetch("/api/run/status");
      if (answer.ok) this.showStatus(await answer.json());
    } catch {
      // the studio is restarting or gone: the status bar says so below, and polling goes on
      this.setStatus("the studio does not answer", "error");
    }
    setTimeout(() => this.poll(), STATUS_PERIOD_MS);
  }

  showStatus(status) {
    const progress = el(this.root, "run-progress");
    const batch = status.batch || null;
    progress.dataset.state = status.state;
    let text = status.state;
    if (batch) {
      const running = (batch.running || []).map((r) => r.simulation);
      text += `: ${batch.done}/${batch.total} simulations ended (${batch.succeeded} succeeded)`;
      if (running.length) text += `, simulation ${running.join(", ")} flying`;
      el(this.root, "run-bar").max = batch.total;
      el(this.root, "run-bar").value = batch.done;
    }
    if (status.state === "finished") text += ` (exit status ${status.exit_status})`;
    if (status.bridge_error) text += ` — ${status.bridge_error}`;
    progress.textContent = text;
    el(this.root, "run-log").textContent = (status.log || []).join("\n");
    el(this.root, "run-stop").disabled = status.state !== "running";
    el(this.root, "run-start").disabled = status.state === "running" || status.state === "stopping";
    if (status.bridge_url && status.bridge_url !== this.bridgeUrl) this.connect(status.bridge_url);
    if (!status.bridge_url && this.bridge) this.disconnect();
    if (batch) this.showReports(batch);
  }

  showReports(batch) {
    const list = el(this.root, "run-reports");
    const expected = batch.results.length + (batch.state === "finished" && batch.dataset_dir ? 1 : 0);
    if (list.childElementCount === expected) return;
    const links = [];
    const root = this.dataRoot(batch);
    const link = (path, label) => {
      const item = document.createElement("li");
      const anchor = document.createElement("a");
      anchor.href = `/reports/${path}`;
      anchor.target = "_blank";
      anchor.textContent = label;
      item.append(anchor);
      return item;
    };
    if (batch.state === "finished" && batch.dataset_dir && root !== null) links.push(link(`${relative(batch.dataset_dir, root)}/index.html`, "the dataset's reports"));
    for (const result of batch.results) {
      if (result.directory && root !== null) {
        links.push(link(`${relative(result.directory, root)}/report.html`,
          `simulation ${result.id}: ${result.success ? "succeeded" : result.outcome}`));
      }
    }
    list.replaceChildren(...links);
  }

  dataRoot(batch) {
    // the dataset folder is DATA_ROOT/Simulations/...: the reports are served from DATA_ROOT
    const folder = batch.dataset_dir || "";
    const at = folder.indexOf("/Simulations/");
    return at >= 0 ? folder.slice(0, at) : null;
  }

  // --- the live view ------------------------------------------------------------------------------------
  connect(url) {
    this.disconnect();
    this.bridgeUrl = url;
    el(this.root, "run-bridge").textContent = `connecting to ${url}`;
    this.bridge = new BridgeClient(url, {
      onOpen: () => { el(this.root, "run-bridge").textContent = `connected to ${url}`; },
      onClose: () => { el(this.root, "run-bridge").textContent = "not connected"; },
      onError: (error) => this.setStatus(error.message, "error"),
    });
    const agents = agentsOf(this.hooks.mission()?.data);
    for (const { id, color } of agents) {
      this.uav(id, color);
      this.bridge.subscribe(`/uav_${id}/ual/pose`, "geometry_msgs/PoseStamped",
        (msg) => this.onPose(id, msg), POSE_THROTTLE_MS);
      this.bridge.subscribe(`/uav_${id}/ual/state`, "uav_abstraction_layer/State",
        (msg) => this.setCell(id, "state", UAL_STATES[msg.state] || String(msg.state)), 200);
      this.bridge.subscribe(`/uav_${id}/mavros/battery`, "sensor_msgs/BatteryState",
        (msg) => this.setCell(id, "battery", msg.percentage === null ? "?" : `${Math.round(msg.percentage * 100)} %`), 500);
      this.bridge.subscribe(`/magna/uav_${id}/navigation`, "magna_msgs/NavigationStep",
        (msg) => this.setCell(id, "role", msg.role), 200);
    }
    this.bridge.subscribe("/magna/sm/mission/status", "magna_msgs/SMStatus", (msg) => this.onMachine(msg));
    this.bridge.subscribe("/magna/gs/critical_events", "magna_msgs/CriticalEvent", (msg) => this.onEvent(
      `UAV ${msg.uav_id} ${msg.event} at ${msg.sim_time.toFixed(1)} s${msg.detail ? ` (${msg.detail})` : ""}`));
    // the operator's own critical event is not a UAV's: it is said only on the topic every manager hears
    this.bridge.subscribe("/magna/gs/critical_event", "std_msgs/String", (msg) => {
      if (msg.data === "operator") this.onEvent("the operator's critical event is raised (until Resume)");
      else if (msg.data === "" && this.operatorCritical) this.onEvent("the operator's critical event is cleared");
      this.operatorCritical = msg.data === "operator";
    });
  }

  disconnect() {
    if (this.bridge) this.bridge.close();
    this.bridge = null;
    this.bridgeUrl = null;
  }

  uav(id, color) {
    if (!this.uavs.has(id)) {
      const row = document.createElement("tr");
      row.dataset.testid = `uav-row-${id}`;
      for (const cell of ["id", "role", "state", "battery", "position"]) {
        const td = document.createElement("td");
        td.dataset.cell = cell;
        td.textContent = cell === "id" ? `UAV ${id}` : "—";
        row.append(td);
      }
      el(this.root, "uav-table").querySelector("tbody").append(row);
      this.uavs.set(id, { color, trail: [], row, updates: 0 });
    }
    return this.uavs.get(id);
  }

  setCell(id, cell, text) {
    const uav = this.uavs.get(id);
    if (uav) uav.row.querySelector(`[data-cell="${cell}"]`).textContent = text;
  }

  onPose(id, msg) {
    const p = msg.pose.position;
    const uav = this.uavs.get(id);
    if (!uav) return;
    uav.updates += 1;
    this.stats.poses += 1;
    uav.trail.push([p.x, p.y, p.z]);
    if (uav.trail.length > TRAIL_POINTS) uav.trail.shift();
    this.view.setUav(id, [p.x, p.y, p.z], uav.color);
    this.view.setTrail(id, uav.trail);
    this.setCell(id, "position", `${p.x.toFixed(1)}, ${p.y.toFixed(1)}, ${p.z.toFixed(1)}`);
  }

  onMachine(status) {
    this.active.update(status);
    const paths = this.active.paths();
    el(this.root, "run-active").textContent = paths.join(", ") || "—";
    this.graph.lightStates(paths);
  }

  onEvent(text) {
    const item = document.createElement("li");
    item.dataset.testid = "run-event";
    item.textContent = text;
    el(this.root, "run-events").prepend(item);
  }

  // --- commands ------------------------------------------------------------------------------------------
  fillActions() {
    const intent = el(this.root, "command-intent").value;
    const select = el(this.root, "command-action");
    select.replaceChildren(...ACTIONS[intent].map((a) => new Option(a, a)));
  }

  sendCommandForm() {
    const parameters = [];
    for (const row of this.root.querySelectorAll("[data-testid=command-param]")) {
      const name = row.querySelector("[data-field=name]").value.trim();
      if (!name) continue;
      const value = row.querySelector("[data-field=value]").value.trim();
      const number = Number(value);
      parameters.push(value !== "" && Number.isFinite(number)
        ? { name, number, text: "", unit: "" } : { name, number: 0, text: value, unit: "" });
    }
    this.command(el(this.root, "command-intent").value, el(this.root, "command-action").value,
      el(this.root, "command-agent").value.trim() || "all", parameters);
  }

  async command(intent, action, agent, parameters) {
    const answer = el(this.root, "command-answer");
    if (!this.bridge) {
      answer.dataset.result = "error";
      answer.textContent = "no running mission to command: start a run first";
      return;
    }
    try {
      const values = await this.bridge.callService(COMMAND.service, COMMAND.type, { intent, action, agent, parameters });
      answer.dataset.result = values.accepted ? "accepted" : "refused";
      const answers = (values.values || []).map((v) => `${v.name} ${v.text || v.number}${v.unit ? " " + v.unit : ""}`);
      answer.textContent = `${values.accepted ? "accepted" : "refused"}: ${values.message}` +
        (answers.length ? ` (${answers.join(", ")})` : "");
    } catch (error) {
      answer.dataset.result = "error";
      answer.textContent = error.message;
    }
  }

  async pressContinue() {
    if (!this.bridge) return;
    try {
      const values = await this.bridge.callService("/magna/gs/continue", "std_srvs/Trigger", {});
      this.setStatus(values.success ? `continue: ${values.message}` : `continue refused: ${values.message}`);
    } catch (error) {
      this.setStatus(error.message, "error");
    }
  }
}

// magna run files a dataset under the world's and mission's Family/Name: a new document is filed under Studio/.
function runnable(record, fallback) {
  if (!record || !record.data) return null;
  const name = /^[\w.-]+\/[\w.-]+$/.test(record.name || "") ? record.name : `Studio/${fallback}`;
  return { data: record.data, name };
}

function relative(path, root) {
  return path.startsWith(`${root}/`) ? path.slice(root.length + 1) : path;
}
