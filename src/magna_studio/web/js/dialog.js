// The in-page question before a file is replaced (a <dialog>: modal, Escape cancels).

/** Resolve true when the user agrees to replace `path`, false otherwise. */
export function confirmOverwrite(path) {
  const dialog = document.querySelector('[data-testid="confirm-overwrite"]');
  dialog.querySelector('[data-testid="confirm-message"]').textContent = `${path} exists. Replace it?`;
  dialog.returnValue = "";
  return new Promise((resolve) => {
    dialog.addEventListener("close", () => resolve(dialog.returnValue === "yes"), { once: true });
    dialog.showModal();
  });
}
