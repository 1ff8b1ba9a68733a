// Saving a document: a file that exists is replaced only after the user says so in the page's dialog
// (the server answers 409 with {"exists": true} to a save without overwrite).

import { confirmOverwrite } from "./dialog.js";
import { byTestId } from "./dom.js";
import { originOf } from "./file_picker.js";
import { showError, showStatus } from "./status.js";

/** The Save button of a view (`kind`: "world" or "mission"): the path from its Save-as field, the question
 * before replacing a file, the saved path shown. Resolves the saved path, or null when nothing was saved. */
export async function saveFromToolbar(kind, send, data) {
  if (!data) {
    showStatus(`nothing to save: open or create a ${kind} first`, "error");
    return null;
  }
  const input = byTestId(`${kind}-save-path`);
  const path = input.value.trim();
  if (!path) {
    input.focus();
    showStatus(`give the file to save the ${kind} to (Save as)`, "error");
    return null;
  }
  try {
    const saved = await saveWithConfirmation(send, data, path);
    if (saved === null) {
      showStatus(`not saved: ${path} kept as it was`);
      return null;
    }
    byTestId(`${kind}-saved`).textContent = `saved ${saved}`;
    showStatus(`${kind} saved to ${saved}`, "ok");
    return saved;
  } catch (error) {
    showError(error, `cannot save the ${kind}`);
    return null;
  }
}

/** Save through `send(data, path, overwrite)`; resolves the saved path, or null when the user declined. */
export async function saveWithConfirmation(send, data, path) {
  try {
    return (await send(data, path, false)).path || path;
  } catch (error) {
    if (error.status !== 409) throw error;
    if (!(await confirmOverwrite(path))) return null;
    return (await send(data, path, true)).path || path;
  }
}

/** The Save-as path offered for a file just opened: itself, unless it comes from a folder given with
 * --search-path (such as the original ROS-MAGNA's files, which are read, not written). */
export function defaultSavePath(path) {
  const origin = path ? originOf(path) : undefined;
  return path && (origin === undefined || origin === "project") ? path : "";
}
