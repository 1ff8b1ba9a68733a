// Diagnostics of a check, shown twice: as a list (each item jumps to its place) and on the fields themselves
// (a data-testid="field-error" element beside the input whose data-path equals the diagnostic's path or is
// its nearest ancestor). Each check replaces the previous one's: an error the server no longer returns goes.

import { nearestPath } from "./json_path.js";

/** The list: [{severity, path, message, line}]; `onSelect(path)` when one is clicked or chosen by keyboard. */
export function renderDiagnosticsList(list, diagnostics, onSelect) {
  list.replaceChildren();
  if (!diagnostics.length) {
    const none = document.createElement("li");
    none.className = "none";
    none.textContent = "No problems found.";
    list.append(none);
    return;
  }
  for (const diagnostic of sortDiagnostics(diagnostics)) {
    const item = document.createElement("li");
    item.className = `diagnostic ${diagnostic.severity}`;
    item.dataset.testid = "diagnostic";
    item.dataset.path = diagnostic.path || "";
    item.dataset.severity = diagnostic.severity;
    item.tabIndex = 0;
    const where = document.createElement("code");
    where.className = "where";
    where.textContent = diagnostic.path || "(whole file)";
    if (diagnostic.line) item.title = String(diagnostic.line); // the line `magna world|mission check` prints
    const message = document.createElement("span");
    message.className = "message";
    message.textContent = diagnostic.message;
    item.append(severityMark(diagnostic.severity), where, message);
    item.addEventListener("click", () => onSelect(diagnostic.path || ""));
    item.addEventListener("keydown", (event) => {
      if (event.key === "Enter" || event.key === " ") {
        event.preventDefault();
        onSelect(diagnostic.path || "");
      }
    });
    list.append(item);
  }
}

/** Put each diagnostic on its field in `form` (the server's; the page's own JSON errors stay). */
export function showFieldErrors(form, diagnostics) {
  for (const old of form.querySelectorAll('[data-testid="field-error"]:not([data-local="true"])')) old.remove();
  for (const marked of form.querySelectorAll(".invalid")) {
    marked.classList.remove("invalid");
    marked.removeAttribute("aria-invalid");
  }
  const bound = [...form.querySelectorAll("[data-path]")].filter((element) => element.dataset.testid !== "field-error"
    && element.dataset.role !== "append");
  const byPath = new Map();
  for (const element of bound) if (!byPath.has(element.dataset.path)) byPath.set(element.dataset.path, element);
  for (const diagnostic of sortDiagnostics(diagnostics)) {
    const path = nearestPath(byPath.keys(), diagnostic.path || "");
    if (path === null) continue;
    const target = byPath.get(path);
    target.classList.add("invalid");
    if (diagnostic.severity === "error") target.setAttribute("aria-invalid", "true");
    const error = document.createElement("div");
    error.className = `field-error ${diagnostic.severity}`;
    error.dataset.testid = "field-error";
    error.dataset.path = path;
    error.dataset.severity = diagnostic.severity;
    error.dataset.diagnosticPath = diagnostic.path || "";
    const rest = diagnostic.path && diagnostic.path !== path ? `${diagnostic.path.slice(path.length).replace(/^\./, "")}: ` : "";
    error.textContent = `${rest}${diagnostic.message}`;
    const home = target.closest(".field")?.querySelector(".field-errors") || target.querySelector(".field-errors");
    if (home) home.append(error);
    else target.after(error);
  }
}

/** Per tree item (the nearest one to each diagnostic's path): {errors, warnings}. */
export function countByItem(itemPaths, diagnostics) {
  const counts = new Map();
  for (const diagnostic of diagnostics) {
    const path = nearestPath(itemPaths, diagnostic.path || "");
    if (path === null) continue;
    const count = counts.get(path) || { errors: 0, warnings: 0 };
    if (diagnostic.severity === "error") count.errors++;
    else count.warnings++;
    counts.set(path, count);
  }
  return counts;
}

/** A one-line summary: "2 errors, 1 warning" or "no problems". */
export function summarise(diagnostics) {
  const errors = diagnostics.filter((d) => d.severity === "error").length;
  const warnings = diagnostics.length - errors;
  if (!diagnostics.length) return "no problems";
  const plural = (n, word) => `${n} ${word}${n === 1 ? "" : "s"}`;
  return [errors && plural(errors, "error"), warnings && plural(warnings, "warning")].filter(Boolean).join(", ");
}

function sortDiagnostics(diagnostics) {
  const rank = (d) => (d.severity === "error" ? 0 : 1);
  return [...diagnostics].sort((a, b) => rank(a) - rank(b));
}

function severityMark(severity) {
  const mark = document.createElement("span");
  mark.className = "severity";
  mark.textContent = severity === "error" ? "error" : "warning";
  return mark;
}
