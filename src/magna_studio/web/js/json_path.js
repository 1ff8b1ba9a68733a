// JSON paths as the MAGNA loaders write them: `scenario.volumes[0].geometries[1].dimensions`
// (a key after a dot, an index in brackets, "" for the whole document). Every form input carries
// one in data-path; this module reads and writes the document at such a path.

/** "a.b[2].c" -> ["a", "b", 2, "c"]; "" -> []. A bracketed quoted key (["x.y"]) is read as a key. */
export function parsePath(path) {
  const parts = [];
  const pattern = /\[(\d+)\]|\["((?:[^"\\]|\\.)*)"\]|\.?([^.[\]]+)/g;
  let match;
  while ((match = pattern.exec(path)) !== null) {
    if (match[1] !== undefined) parts.push(Number(match[1]));
    else if (match[2] !== undefined) parts.push(JSON.parse(`"${match[2]}"`));
    else parts.push(match[3]);
  }
  return parts;
}

/** ["a", "b", 2] -> "a.b[2]": the inverse of parsePath. */
export function formatPath(parts) {
  let path = "";
  for (const part of parts) {
    if (typeof part === "number") path += `[${part}]`;
    else if (/^[^.[\]"]+$/.test(part)) path += path ? `.${part}` : part;
    else path += `[${JSON.stringify(part)}]`;
  }
  return path;
}

/** The path one level down. */
export function childPath(base, key) {
  return formatPath([...parsePath(base), key]);
}

/** The value at `path`, or undefined when any step is missing. */
export function getAt(doc, path) {
  let value = doc;
  for (const part of parsePath(path)) {
    if (value === null || typeof value !== "object") return undefined;
    value = value[part];
  }
  return value;
}

/** Set the value at `path`, creating objects (or lists, before an index) on the way. */
export function setAt(doc, path, value) {
  const parts = parsePath(path);
  if (parts.length === 0) throw new Error("cannot replace the whole document through a field");
  let parent = doc;
  parts.slice(0, -1).forEach((part, i) => {
    if (parent[part] === null || typeof parent[part] !== "object") {
      parent[part] = typeof parts[i + 1] === "number" ? [] : {};
    }
    parent = parent[part];
  });
  parent[parts[parts.length - 1]] = value;
}

/** Remove the key (or the list item) at `path`; nothing happens when it is absent. */
export function deleteAt(doc, path) {
  const parts = parsePath(path);
  const parent = getAt(doc, formatPath(parts.slice(0, -1)));
  const last = parts[parts.length - 1];
  if (Array.isArray(parent) && typeof last === "number") parent.splice(last, 1);
  else if (parent && typeof parent === "object") delete parent[last];
}

/** True when `ancestor` is `path` itself or contains it ("" contains everything). */
export function isAncestorOrSelf(ancestor, path) {
  if (ancestor === path || ancestor === "") return true;
  if (!path.startsWith(ancestor)) return false;
  const next = path[ancestor.length];
  return next === "." || next === "[";
}

/** Of `candidates`, the one equal to `path` or, failing that, its nearest ancestor; null if none. */
export function nearestPath(candidates, path) {
  let best = null;
  for (const candidate of candidates) {
    if (isAncestorOrSelf(candidate, path) && (best === null || candidate.length > best.length)) best = candidate;
  }
  return best;
}
