// The mission's state machine as the server draws it (graphviz SVG), inline: scaled to fit, dragged to pan,
// wheel (or + / -) to zoom, 0 to fit again. States can be lit (lightStates: class "active", for the Run view)
// or marked selected; clicking one tells onSelectState its state path.
//
// How a state is found in the picture is one function, statePathOf: the server marks each state's group
// (a leaf's node, a container's box) with data-state="<magna_sm path>", e.g. "/MISSION/1_take_off"; an SVG
// without the marks is read from graphviz's titles (<title>/MISSION/x</title>, <title>cluster_/MISSION/y</title>).

const ZOOM_STEP = 1.2;
const CLICK_TOLERANCE_PX = 4;
const CLUSTER_PREFIX = "cluster_";

/** The SVG elements that stand for the state at `path` (a state's node, or a container's box). */
export function nodesOfState(svg, path) {
  return [...svg.querySelectorAll("g.node, g.cluster, [data-state]")].filter((group) => statePathOf(group) === path);
}

/** The state path a graphviz group stands for, or null (an outcome box, the graph itself). */
export function statePathOf(group) {
  if (group.hasAttribute("data-state")) return group.getAttribute("data-state");
  if (group.hasAttribute("data-outcome")) return null;
  const title = group.querySelector(":scope > title")?.textContent?.trim() ?? "";
  if (group.classList.contains("cluster")) return title.startsWith(CLUSTER_PREFIX) ? title.slice(CLUSTER_PREFIX.length) : null;
  if (!group.classList.contains("node") || title.includes("/:") || title.endsWith("/__anchor")) return null;
  return title || null;
}

export class MissionGraph {
  /** Shows SVGs in `container`; `onSelectState(path)` when a state is clicked. */
  constructor(container, { onSelectState } = {}) {
    this.container = container;
    this.onSelectState = onSelectState || (() => {});
    this.svg = null;
    this.full = null; // the whole picture's viewBox {x, y, width, height}
    this.box = null; // the part shown now
    this.#listen();
    this.clear("No mission yet.");
  }

  /** Show a graphviz SVG (text). Without one (null or ""), the last picture stays, marked stale, or
   * `emptyMessage` shows when there is none. */
  setSvg(text, emptyMessage = "No picture of the state machine: fix the errors listed.") {
    if (!text) {
      if (this.svg) this.container.dataset.stale = "true";
      else this.clear(emptyMessage);
      return;
    }
    delete this.container.dataset.stale;
    const parsed = new DOMParser().parseFromString(text, "image/svg+xml");
    const svg = parsed.documentElement;
    if (svg.nodeName !== "svg" || parsed.querySelector("parsererror")) {
      this.clear("The server's picture of the state machine could not be read.");
      return;
    }
    for (const script of svg.querySelectorAll("script, foreignObject")) script.remove();
    for (const element of svg.querySelectorAll("*")) {
      for (const attribute of [...element.attributes]) if (/^on/i.test(attribute.name)) element.removeAttribute(attribute.name);
    }
    const keep = this.svg && this.box ? { ...this.box } : null;
    const view = svg.viewBox.baseVal;
    this.full = view && view.width && view.height ? { x: view.x, y: view.y, width: view.width, height: view.height }
      : { x: 0, y: 0, width: parseFloat(svg.getAttribute("width")) || 100, height: parseFloat(svg.getAttribute("height")) || 100 };
    svg.removeAttribute("width");
    svg.removeAttribute("height");
    svg.setAttribute("preserveAspectRatio", "xMidYMid meet");
    svg.classList.add("state-graph");
    this.svg = document.importNode(svg, true);
    this.container.replaceChildren(this.svg);
    const lit = this.lit || [];
    // A redraw after an edit keeps the user's pan and zoom when the picture keeps its size.
    if (keep && this.previousFull && Math.abs(this.previousFull.width - this.full.width) < 1
        && Math.abs(this.previousFull.height - this.full.height) < 1) this.#show(keep);
    else this.fit();
    this.previousFull = { ...this.full };
    this.lightStates(lit);
    this.markSelected(this.selectedPaths || []);
  }

  clear(message) {
    delete this.container.dataset.stale;
    this.svg = null;
    this.full = this.box = null;
    const note = document.createElement("p");
    note.className = "empty";
    note.textContent = message;
    this.container.replaceChildren(note);
  }

  /** Show the whole picture. */
  fit() {
    if (this.full) this.#show({ ...this.full });
  }

  /** Light the states at `paths` (class "active"); every other state is unlit. */
  lightStates(paths) {
    this.lit = [...paths];
    if (!this.svg) return;
    for (const old of this.svg.querySelectorAll(".active")) old.classList.remove("active");
    for (const path of this.lit) for (const node of nodesOfState(this.svg, path)) node.classList.add("active");
  }

  /** Mark the states at `paths` as the ones selected in the tree (class "selected"; [] for none); with
   * `reveal`, pan so that the first of them is in view. */
  markSelected(paths, { reveal = false } = {}) {
    this.selectedPaths = [...paths];
    if (!this.svg) return;
    for (const old of this.svg.querySelectorAll(".selected")) old.classList.remove("selected");
    const marked = this.selectedPaths.flatMap((path) => nodesOfState(this.svg, path));
    for (const node of marked) node.classList.add("selected");
    if (reveal && marked.length) this.#reveal(marked[0]);
  }

  /** Pan (at the same zoom) so that `element` is in view, when it is not already. */
  #reveal(element) {
    const view = this.container.getBoundingClientRect();
    const box = element.getBoundingClientRect();
    if (!view.width || !view.height) return;
    const inside = box.left >= view.left && box.right <= view.right && box.top >= view.top && box.bottom <= view.bottom;
    if (inside) return;
    this.#pan(view.left + view.width / 2 - (box.left + box.width / 2), view.top + view.height / 2 - (box.top + box.height / 2));
  }

  #show(box) {
    this.box = box;
    this.svg?.setAttribute("viewBox", `${box.x} ${box.y} ${box.width} ${box.height}`);
  }

  /** Picture units per screen pixel now (the picture is scaled to fit, keeping its aspect). */
  #unitsPerPixel() {
    const rect = this.container.getBoundingClientRect();
    return Math.max(this.box.width / Math.max(rect.width, 1), this.box.height / Math.max(rect.height, 1));
  }

  #zoom(factor, clientX, clientY) {
    if (!this.box) return;
    const rect = this.container.getBoundingClientRect();
    const scale = this.#unitsPerPixel();
    // the picture point under the pointer stays under it
    const cx = clientX ?? rect.left + rect.width / 2;
    const cy = clientY ?? rect.top + rect.height / 2;
    const px = this.box.x + this.box.width / 2 + (cx - rect.left - rect.width / 2) * scale;
    const py = this.box.y + this.box.height / 2 + (cy - rect.top - rect.height / 2) * scale;
    const width = this.box.width / factor;
    const height = this.box.height / factor;
    this.#show({ x: px - (px - this.box.x) / factor, y: py - (py - this.box.y) / factor, width, height });
  }

  #pan(dxPixels, dyPixels) {
    if (!this.box) return;
    const scale = this.#unitsPerPixel();
    this.#show({ ...this.box, x: this.box.x - dxPixels * scale, y: this.box.y - dyPixels * scale });
  }

  #listen() {
    const element = this.container;
    let drag = null;
    element.addEventListener("pointerdown", (event) => {
      if (!this.svg || event.button !== 0) return;
      drag = { x: event.clientX, y: event.clientY, startX: event.clientX, startY: event.clientY, moved: false };
      element.setPointerCapture(event.pointerId);
    });
    element.addEventListener("pointermove", (event) => {
      if (!drag) return;
      if (Math.hypot(event.clientX - drag.startX, event.clientY - drag.startY) > CLICK_TOLERANCE_PX) drag.moved = true;
      if (drag.moved) {
        this.#pan(event.clientX - drag.x, event.clientY - drag.y);
        element.classList.add("panning");
      }
      drag.x = event.clientX;
      drag.y = event.clientY;
    });
    element.addEventListener("pointerup", (event) => {
      if (!drag) return;
      const wasClick = !drag.moved;
      drag = null;
      element.classList.remove("panning");
      if (!wasClick) return;
      // pointer capture retargets the event to the container: find what lies under the pointer
      const under = document.elementFromPoint(event.clientX, event.clientY);
      const group = under?.closest("[data-state], g.node, g.cluster");
      const path = group && statePathOf(group);
      if (path) this.onSelectState(path);
    });
    element.addEventListener("wheel", (event) => {
      if (!this.svg) return;
      event.preventDefault();
      this.#zoom(event.deltaY < 0 ? ZOOM_STEP : 1 / ZOOM_STEP, event.clientX, event.clientY);
    }, { passive: false });
    element.addEventListener("keydown", (event) => {
      const step = 40;
      const actions = {
        "+": () => this.#zoom(ZOOM_STEP), "=": () => this.#zoom(ZOOM_STEP), "-": () => this.#zoom(1 / ZOOM_STEP),
        0: () => this.fit(), ArrowLeft: () => this.#pan(step, 0), ArrowRight: () => this.#pan(-step, 0),
        ArrowUp: () => this.#pan(0, step), ArrowDown: () => this.#pan(0, -step),
      };
      if (actions[event.key] && this.svg) {
        event.preventDefault();
        actions[event.key]();
      }
    });
  }
}

/** A graph showing `svg` in `container` (the Run view's way to make one). */
export function showGraph(container, svg, options = {}) {
  const graph = new MissionGraph(container, options);
  graph.setSvg(svg);
  return graph;
}
