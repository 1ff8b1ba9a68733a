// The page's elements are named by data-testid (the browser tests use the same names): one lookup for all.

/** The element named `id` under `root` (the whole page by default), or null. */
export function byTestId(id, root = document) {
  return root.querySelector(`[data-testid="${id}"]`);
}
