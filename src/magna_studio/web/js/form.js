// Form fields bound to a JSON document. Each input carries data-path, the JSON path of the value it edits
// (a vector's row carries the vector's path, each of its inputs its item's path); an edit writes the document
// at that path at once and then calls onEdit(path, {structural}). The document is always what the user typed:
// a number field that does not read as a number stores the text, so the server's check names the problem on
// that field (only text that is not JSON at all stays in the page, as a local field error).

import { childPath, deleteAt, getAt, setAt } from "./json_path.js";

let nextId = 0;
const uniqueId = () => `field-${++nextId}`;

/** JSON on one line, or one item per line for a list of lists/objects (paths, poses) so it stays readable. */
export function compactJson(value) {
  if (value === undefined) return "";
  const nested = (item) => item !== null && typeof item === "object";
  if (Array.isArray(value) && value.length > 1 && value.some(nested)) {
    return `[\n  ${value.map((item) => JSON.stringify(item)).join(",\n  ")}\n]`;
  }
  if (nested(value) && !Array.isArray(value) && Object.keys(value).length > 1) {
    return `{\n  ${Object.entries(value).map(([k, v]) => `${JSON.stringify(k)}: ${JSON.stringify(v)}`).join(",\n  ")}\n}`;
  }
  return JSON.stringify(value);
}

/** Text of a number field -> a number, or the text itself when it is not one (the check reports it). */
function readNumber(text) {
  const trimmed = text.trim();
  if (trimmed === "") return null;
  const number = Number(trimmed);
  return Number.isFinite(number) ? number : trimmed;
}

const numberText = (value) => (value === undefined || value === null ? "" : String(value));

export class BoundForm {
  /** `getDoc()` gives the document being edited; `onEdit(path, {structural})` runs after each change. */
  constructor(element, getDoc, onEdit) {
    this.element = element;
    this.getDoc = getDoc;
    this.onEdit = onEdit;
    element.addEventListener("submit", (event) => event.preventDefault());
  }

  clear(message = "") {
    this.element.replaceChildren();
    if (message) {
      const note = document.createElement("p");
      note.className = "empty";
      note.textContent = message;
      this.element.append(note);
    }
  }

  /** A titled group of fields; returns the element to add fields to. */
  section(title, parent = this.element) {
    const fieldset = document.createElement("fieldset");
    const legend = document.createElement("legend");
    legend.textContent = title;
    fieldset.append(legend);
    parent.append(fieldset);
    return fieldset;
  }

  /** A line of explanation. */
  note(parent, text) {
    const note = document.createElement("p");
    note.className = "note";
    note.textContent = text;
    parent.append(note);
    return note;
  }

  /**
   * One field. `spec`: {path, label, kind, optional, doc, choices, size, rows, cols, axes, structural,
   * append (json only): {label, choices: [{label, group?, apply(current value) -> new value}]}}.
   * Kinds: text, number, bool, choice, ids (a mission's ids), vector (size numbers), matrix (rows x cols numbers),
   * color (r, g, b 0-255), json (any value as JSON text).
   */
  field(parent, spec) {
    const row = document.createElement("div");
    row.className = `field field-${spec.kind}`;
    row.dataset.fieldPath = spec.path;
    const label = document.createElement("label");
    label.className = "field-label";
    label.textContent = spec.label;
    if (!spec.optional && spec.kind !== "bool") label.classList.add("required");
    const inputs = document.createElement("div");
    inputs.className = "field-inputs";
    const errors = document.createElement("div");
    errors.className = "field-errors";
    errors.id = uniqueId();
    row.append(label, inputs, errors);
    if (spec.doc) {
      const doc = document.createElement("small");
      doc.className = "field-doc";
      doc.textContent = spec.doc;
      row.append(doc);
    }
    const builder = {
      text: this.#text, number: this.#number, ids: this.#ids, bool: this.#bool, choice: this.#choice, vector: this.#vector,
      matrix: this.#matrix, color: this.#color, json: this.#json,
    }[spec.kind] || this.#json;
    const first = builder.call(this, inputs, spec, row);
    if (first) {
      first.id = first.id || uniqueId();
      label.htmlFor = first.id;
    }
    for (const input of inputs.querySelectorAll("input, select, textarea")) {
      input.setAttribute("aria-describedby", errors.id);
    }
    parent.append(row);
    return row;
  }

  // --- writing the document ------------------------------------------------------------------------------------

  #write(spec, value) {
    const doc = this.getDoc();
    if (value === undefined) deleteAt(doc, spec.path);
    else setAt(doc, spec.path, value);
    this.onEdit(spec.path, { structural: Boolean(spec.structural) });
  }

  #value(spec) {
    return getAt(this.getDoc(), spec.path);
  }

  // --- the kinds -------------------------------------------------------------------------------------------------

  #text(inputs, spec) {
    const input = document.createElement("input");
    input.type = "text";
    input.spellcheck = false;
    input.dataset.path = spec.path;
    const value = this.#value(spec);
    input.value = value === undefined || value === null ? "" : typeof value === "string" ? value : JSON.stringify(value);
    input.addEventListener("input", () => {
      this.#write(spec, input.value === "" && spec.optional ? undefined : input.value);
    });
    inputs.append(input);
    return input;
  }

  #numberInput(path, value) {
    const input = document.createElement("input");
    input.type = "text";
    input.inputMode = "decimal";
    input.className = "number";
    input.dataset.path = path;
    input.value = typeof value === "object" && value !== null ? JSON.stringify(value) : numberText(value);
    return input;
  }

  #number(inputs, spec) {
    const input = this.#numberInput(spec.path, this.#value(spec));
    input.addEventListener("input", () => {
      const value = readNumber(input.value);
      this.#write(spec, value === null && spec.optional ? undefined : value);
    });
    inputs.append(input);
    return input;
  }

  /** A mission's ids: "1", "1, 2" (or [1, 2]) or "all" -> 1, [1, 2], "all"; anything else stays text. */
  #ids(inputs, spec) {
    const input = document.createElement("input");
    input.type = "text";
    input.spellcheck = false;
    input.dataset.path = spec.path;
    const value = this.#value(spec);
    input.value = value === undefined || value === null ? "" : Array.isArray(value) ? value.join(", ") : String(value);
    input.addEventListener("input", () => {
      const text = input.value.trim();
      if (text === "") return this.#write(spec, spec.optional ? undefined : null);
      if (text === "all") return this.#write(spec, "all");
      const items = text.replace(/^\[|\]$/g, "").split(",").map((item) => readNumber(item));
      const numbers = items.every((item) => typeof item === "number");
      if (!numbers) return this.#write(spec, text);
      this.#write(spec, items.length === 1 && !text.startsWith("[") && !text.includes(",") ? items[0] : items);
    });
    inputs.append(input);
    return input;
  }

  #bool(inputs, spec) {
    const input = document.createElement("input");
    input.type = "checkbox";
    input.dataset.path = spec.path;
    input.checked = this.#value(spec) === true;
    input.addEventListener("change", () => this.#write(spec, input.checked));
    inputs.append(input);
    return input;
  }

  #choice(inputs, spec) {
    const select = document.createElement("select");
    select.dataset.path = spec.path;
    const value = this.#value(spec);
    const options = (spec.choices || []).map((choice) =>
      typeof choice === "object" && choice !== null ? choice : { value: choice, label: String(choice) });
    if (spec.optional || value === undefined) options.unshift({ value: undefined, label: "—" });
    const known = options.some((option) => option.value === value);
    if (!known && value !== undefined) options.push({ value, label: `${JSON.stringify(value)} (not a known choice)` });
    options.forEach((option, index) => {
      const element = document.createElement("option");
      element.value = String(index);
      element.textContent = option.label;
      if (option.value === value) element.selected = true;
      select.append(element);
    });
    select.addEventListener("change", () => this.#write(spec, options[Number(select.value)].value));
    inputs.append(select);
    return select;
  }

  /** Several numbers written back as one list (all empty and optional: the key goes). */
  #numbers(inputs, spec, shape, row) {
    row.dataset.path = spec.path;
    const value = this.#value(spec);
    const grid = document.createElement("div");
    grid.className = "number-grid";
    grid.style.setProperty("--columns", String(shape.cols));
    const cells = [];
    for (let r = 0; r < shape.rows; r++) {
      for (let c = 0; c < shape.cols; c++) {
        const itemPath = shape.nested ? childPath(childPath(spec.path, r), c) : childPath(spec.path, c);
        const item = shape.nested ? (Array.isArray(value) && Array.isArray(value[r]) ? value[r][c] : undefined)
          : (Array.isArray(value) ? value[c] : undefined);
        const input = this.#numberInput(itemPath, item);
        const axis = shape.labels ? shape.labels[shape.nested ? r * shape.cols + c : c] : "";
        if (axis) {
          input.title = axis;
          input.placeholder = axis;
          input.setAttribute("aria-label", `${spec.label} ${axis}`);
        }
        cells.push(input);
        grid.append(input);
      }
    }
    const collect = () => {
      const numbers = cells.map((cell) => readNumber(cell.value));
      if (numbers.every((n) => n === null) && spec.optional) return undefined;
      if (!shape.nested) return numbers;
      return Array.from({ length: shape.rows }, (_, r) => numbers.slice(r * shape.cols, (r + 1) * shape.cols));
    };
    for (const cell of cells) cell.addEventListener("input", () => { this.#write(spec, collect()); row.dispatchEvent(new Event("numbers")); });
    inputs.append(grid);
    return { first: cells[0], cells };
  }

  #vector(inputs, spec, row) {
    return this.#numbers(inputs, spec, { rows: 1, cols: spec.size || 3, nested: false, labels: spec.axes }, row).first;
  }

  #matrix(inputs, spec, row) {
    return this.#numbers(inputs, spec, { rows: spec.rows, cols: spec.cols, nested: true, labels: spec.axes }, row).first;
  }

  /** r, g, b (0-255) and a colour picker that sets all three. */
  #color(inputs, spec, row) {
    const { first, cells } = this.#numbers(inputs, { ...spec, size: 3 }, { rows: 1, cols: 3, nested: false, labels: ["r", "g", "b"] }, row);
    const picker = document.createElement("input");
    picker.type = "color";
    picker.setAttribute("aria-label", `${spec.label} picker`);
    const hex = (n) => Math.max(0, Math.min(255, Math.round(Number(n) || 0))).toString(16).padStart(2, "0");
    const sync = () => { picker.value = `#${cells.map((cell) => hex(cell.value)).join("")}`; };
    sync();
    row.addEventListener("numbers", sync);
    picker.addEventListener("input", () => {
      const rgb = [1, 3, 5].map((i) => parseInt(picker.value.slice(i, i + 2), 16));
      cells.forEach((cell, i) => { cell.value = String(rgb[i]); });
      this.#write(spec, rgb);
    });
    inputs.querySelector(".number-grid").append(picker);
    return first;
  }

  /** Any value as JSON text; text that is not JSON stays in the page with a local error. */
  #json(inputs, spec, row) {
    const area = document.createElement("textarea");
    area.dataset.path = spec.path;
    area.spellcheck = false;
    const show = () => {
      area.value = compactJson(this.#value(spec));
      // tall enough for its lines, and for a long line wrapped at about 40 characters
      const lines = area.value.split("\n").reduce((n, line) => n + Math.max(1, Math.ceil(line.length / 40)), 0);
      area.rows = Math.min(12, Math.max(1, lines));
    };
    show();
    area.addEventListener("input", () => {
      const text = area.value.trim();
      if (text === "" && spec.optional) {
        setLocalError(row, spec.path, null);
        this.#write(spec, undefined);
        return;
      }
      let value;
      try {
        value = JSON.parse(text);
      } catch {
        setLocalError(row, spec.path, "not valid JSON yet: the document keeps the last valid value");
        return;
      }
      setLocalError(row, spec.path, null);
      this.#write(spec, value);
    });
    inputs.append(area);
    if (spec.append && spec.append.choices.length) inputs.append(this.#appendSelect(spec, row, show));
    return area;
  }

  /** A select that changes a JSON field by a choice (add a pose of the world, set "from utm", ...). */
  #appendSelect(spec, row, show) {
    const select = document.createElement("select");
    select.className = "append";
    select.setAttribute("aria-label", `${spec.label}: ${spec.append.label}`);
    select.dataset.role = "append";
    select.dataset.for = spec.path;
    select.append(new Option(spec.append.label, ""));
    const groups = new Map();
    spec.append.choices.forEach((choice, index) => {
      const option = new Option(choice.label, String(index));
      if (!choice.group) {
        select.append(option);
        return;
      }
      if (!groups.has(choice.group)) {
        const group = document.createElement("optgroup");
        group.label = choice.group;
        groups.set(choice.group, group);
        select.append(group);
      }
      groups.get(choice.group).append(option);
    });
    select.addEventListener("change", () => {
      if (select.value === "") return;
      const choice = spec.append.choices[Number(select.value)];
      this.#write(spec, choice.apply(structuredClone(this.#value(spec))));
      setLocalError(row, spec.path, null);
      show();
      select.value = "";
    });
    return select;
  }
}

/** Show (message) or clear (null) the page's own error on a field (text that is not JSON). */
function setLocalError(row, path, message) {
  const errors = row.querySelector(".field-errors");
  errors.querySelector('[data-local="true"]')?.remove();
  if (!message) return;
  const element = document.createElement("div");
  element.className = "field-error error";
  element.dataset.testid = "field-error";
  element.dataset.path = path;
  element.dataset.local = "true";
  element.textContent = message;
  errors.append(element);
}

/** A row at the top of a part's form that carries the part's own diagnostics (data-path = the part's path). */
export function objectErrorsRow(path) {
  const row = document.createElement("div");
  row.className = "field object-errors";
  row.dataset.path = path;
  const errors = document.createElement("div");
  errors.className = "field-errors";
  row.append(errors);
  return row;
}
