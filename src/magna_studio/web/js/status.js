// The status bar at the foot of the page: the last thing that happened, errors in red.

const bar = () => document.querySelector('[data-testid="status"]');

/** Show `message`; level is "info", "ok" or "error". */
export function showStatus(message, level = "info") {
  const element = bar();
  if (!element) return;
  element.textContent = message;
  element.dataset.level = level;
}

/** Show an error (an ApiError's message is the server's own sentence). */
export function showError(error, context = "") {
  const message = error && error.message ? error.message : String(error);
  showStatus(context ? `${context}: ${message}` : message, "error");
}
