// What is open in the designer, shared by the views: the World and Mission tabs write it, the Mission tab
// checks against the world, and the Run view starts `magna run` with them.
// Events: "world" and "mission" (detail: the new record), sent when a document is opened, created or edited.

class Session extends EventTarget {
  constructor() {
    super();
    this.world = null; // {data, path, name}: path null until saved or opened from a file
    this.mission = null;
  }

  setWorld(record) {
    this.world = record;
    this.dispatchEvent(new CustomEvent("world", { detail: record }));
  }

  setMission(record) {
    this.mission = record;
    this.dispatchEvent(new CustomEvent("mission", { detail: record }));
  }
}

export const session = new Session();
