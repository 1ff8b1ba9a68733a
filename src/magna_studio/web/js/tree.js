// A tree of the document's parts (volumes -> geometries -> pose sets; containers -> states). Each item is a
// treeitem with data-testid="tree-item" and data-path (the JSON path of the part); arrow keys move the
// selection, and each item shows how many errors and warnings its own part has.

export class Tree {
  /** `onSelect(path)` runs when the user selects an item. */
  constructor(element, onSelect) {
    this.element = element;
    this.onSelect = onSelect;
    this.selected = null;
    element.addEventListener("keydown", (event) => this.#key(event));
  }

  /** nodes: [{path, label, detail?, kind?, children?}]. */
  render(nodes, selected) {
    this.selected = selected;
    const list = document.createElement("ul");
    list.className = "tree-list";
    for (const node of nodes) list.append(this.#item(node, 1));
    this.element.replaceChildren(list);
    if (!this.#items().some((item) => item.dataset.path === selected)) this.selected = null;
    this.#mark();
  }

  /** Mark the item of `path` selected (no callback). */
  select(path) {
    this.selected = path;
    this.#mark();
  }

  /** counts: Map path -> {errors, warnings}; each item gets its own part's counts. */
  setBadges(counts) {
    for (const item of this.#items()) {
      const badge = item.querySelector(":scope > .tree-row > .badges");
      const count = counts.get(item.dataset.path);
      badge.replaceChildren();
      item.classList.toggle("has-error", Boolean(count && count.errors));
      if (!count) continue;
      for (const [severity, n] of [["error", count.errors], ["warning", count.warnings]]) {
        if (!n) continue;
        const span = document.createElement("span");
        span.className = `badge ${severity}`;
        span.textContent = String(n);
        span.title = `${n} ${severity}${n > 1 ? "s" : ""}`;
        badge.append(span);
      }
    }
  }

  paths() {
    return this.#items().map((item) => item.dataset.path);
  }

  #item(node, level) {
    const item = document.createElement("li");
    item.setAttribute("role", "treeitem");
    item.setAttribute("aria-level", String(level));
    item.dataset.testid = "tree-item";
    item.dataset.path = node.path;
    if (node.kind) item.dataset.kind = node.kind;
    const row = document.createElement("div");
    row.className = "tree-row";
    row.style.setProperty("--level", String(level - 1));
    const label = document.createElement("span");
    label.className = "tree-label";
    label.textContent = node.label;
    row.append(label);
    if (node.detail) {
      const detail = document.createElement("span");
      detail.className = "tree-detail";
      detail.textContent = node.detail;
      row.append(detail);
    }
    const badges = document.createElement("span");
    badges.className = "badges";
    row.append(badges);
    item.append(row);
    row.addEventListener("click", () => this.#choose(node.path));
    if (node.children && node.children.length) {
      item.setAttribute("aria-expanded", "true");
      const group = document.createElement("ul");
      group.setAttribute("role", "group");
      for (const child of node.children) group.append(this.#item(child, level + 1));
      item.append(group);
    }
    return item;
  }

  #items() {
    return [...this.element.querySelectorAll('[role="treeitem"]')];
  }

  #mark() {
    const items = this.#items();
    const current = items.find((item) => item.dataset.path === this.selected) || null;
    for (const item of items) {
      item.setAttribute("aria-selected", String(item === current));
      item.tabIndex = item === current || (!current && item === items[0]) ? 0 : -1;
    }
  }

  #choose(path) {
    this.select(path);
    this.onSelect(path);
  }

  #key(event) {
    const items = this.#items();
    if (!items.length) return;
    const index = items.findIndex((item) => item.dataset.path === this.selected);
    const target = { ArrowDown: index + 1, ArrowUp: index - 1, Home: 0, End: items.length - 1 }[event.key];
    if (target === undefined) {
      if ((event.key === "Enter" || event.key === " ") && event.target.dataset.path) {
        event.preventDefault();
        this.#choose(event.target.dataset.path);
      }
      return;
    }
    event.preventDefault();
    const next = items[Math.max(0, Math.min(items.length - 1, target))];
    this.#choose(next.dataset.path);
    next.focus();
  }
}
