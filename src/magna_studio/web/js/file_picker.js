// The "open" field of a view: a text input for a name or a path, with the known files as suggestions
// (a datalist from /api/files), opened with the Open button or Enter.

import { listFiles } from "./api.js";
import { showError } from "./status.js";

const origins = new Map(); // absolute path -> "project" or the search folder it was found in

/** Where a listed file comes from: "project", a search folder given to magna studio, or undefined (not listed). */
export const originOf = (path) => origins.get(path);

/** Fill the input's datalist with the files of `kind`; `open(spec)` runs on Open or Enter. */
export function setUpFilePicker(input, button, kind, open) {
  const datalist = document.getElementById(input.getAttribute("list"));
  const run = () => {
    const spec = input.value.trim();
    if (spec) open(spec);
    else input.focus();
  };
  button.addEventListener("click", run);
  input.addEventListener("keydown", (event) => {
    if (event.key === "Enter") {
      event.preventDefault();
      run();
    }
  });
  return listFiles(kind).then((answer) => {
    datalist.replaceChildren();
    for (const file of answer.files || []) {
      origins.set(file.path, file.origin);
      const option = document.createElement("option");
      option.value = file.name || file.path;
      option.label = `${file.name}  (${file.origin === "project" ? "project" : file.origin || file.path})`;
      datalist.append(option);
    }
  }).catch((error) => showError(error, `cannot list the ${kind} files`));
}
