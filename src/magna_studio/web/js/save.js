// Saving a document: a file that exists is replaced only after the user says so in the page's dialog
// (the server answers 409 with {"exists": true} to a save without overwrite).

import { confirmOverwrite } from "./dialog.js";
import { originOf } from "./file_picker.js";

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
