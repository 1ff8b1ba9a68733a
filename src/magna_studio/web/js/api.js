// The HTTP API of `magna studio` (magna_studio.server). Every call returns the parsed JSON body or
// throws an ApiError carrying the server's message ({"error": ...}) and the HTTP status.

export class ApiError extends Error {
  constructor(message, status, body) {
    super(message);
    this.name = "ApiError";
    this.status = status;
    this.body = body || {};
  }
}

async function request(method, url, body) {
  let response;
  try {
    response = await fetch(url, {
      method,
      // the studio refuses a POST without X-Magna-Studio (a page of another site cannot send it)
      headers: body === undefined ? {} : { "Content-Type": "application/json", "X-Magna-Studio": "1" },
      body: body === undefined ? undefined : JSON.stringify(body),
    });
  } catch (error) {
    throw new ApiError(`cannot reach magna studio (${url}: ${error.message}): is it still running?`, 0);
  }
  const text = await response.text();
  let parsed = null;
  try {
    parsed = text ? JSON.parse(text) : {};
  } catch {
    parsed = null;
  }
  if (!response.ok) {
    const message = parsed && typeof parsed.error === "string" ? parsed.error
      : `${method} ${url}: HTTP ${response.status}${text ? `: ${text.slice(0, 200)}` : ""}`;
    throw new ApiError(message, response.status, parsed);
  }
  if (parsed === null) throw new ApiError(`${method} ${url}: the answer is not JSON`, response.status);
  return parsed;
}

const get = (url) => request("GET", url);
const post = (url, body) => request("POST", url, body);

/** {files: [{name, path, origin}]} of kind "world" or "mission". */
export const listFiles = (kind) => get(`/api/files?kind=${encodeURIComponent(kind)}`);

export const openWorld = (spec) => post("/api/world/open", { spec });
export const newWorld = () => post("/api/world/new", {});
export const checkWorld = (data, source, seed) => post("/api/world/check", withSeed({ data, source }, seed));
export const saveWorld = (data, path, overwrite) => post("/api/world/save", { data, path, overwrite: Boolean(overwrite) });

export const openMission = (spec) => post("/api/mission/open", { spec });
export const newMission = () => post("/api/mission/new", {});
export const checkMission = (data, source, world, seed) =>
  post("/api/mission/check", withSeed({ data, source, world: world || null }, seed));
export const saveMission = (data, path, overwrite) => post("/api/mission/save", { data, path, overwrite: Boolean(overwrite) });
export const stateTypes = () => get("/api/mission/state_types");

function withSeed(body, seed) {
  if (seed !== undefined && seed !== null) body.seed = seed;
  return body;
}
