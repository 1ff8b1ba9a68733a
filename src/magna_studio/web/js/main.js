// MAGNA Studio's page: the World and Mission designers in their tabs; the Run view is wired here too
// (js/run_view.js), from the hooks of `studio` below.

import { MissionGraph } from "./mission_graph.js";
import { MissionEditor } from "./mission_editor.js";
import { RunView } from "./run_view.js";
import { session } from "./session.js";
import { showStatus } from "./status.js";
import { setUpTabs } from "./tabs.js";
import { WorldEditor } from "./world_editor.js";
import { WorldView } from "./world_view.js";

const world = new WorldEditor();
const mission = new MissionEditor();

/** What the other views (Run) read of the designers. */
export const studio = {
  session,
  world: () => session.world, // {data, path, name, source} | null
  mission: () => session.mission,
  scene: () => world.scene, // the world's last laid-out scene (S) | null
  graphSvg: () => mission.graphSvg, // the mission's last graph | null
  worldEditor: world,
  missionEditor: mission,
};

setUpTabs((name) => {
  if (name === "mission") mission.onShow();
  else mission.onHide();
});

const run = new RunView(document.querySelector("[data-testid=run-view]"), studio,
  (container) => new WorldView(container), (container) => new MissionGraph(container), showStatus);
studio.run = run;

Promise.all([world.ready, mission.ready]).then(() => {
  document.body.dataset.ready = "true"; // for browser tests: the file lists and state types have been asked for
  showStatus("Ready: open a world or a mission by name or path, or start a new one.");
});
