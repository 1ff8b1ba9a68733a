// The World / Mission / Run tabs: WAI-ARIA tabs (arrow keys, Home, End), the choice kept in the URL's hash.

/** Wire the tablist; `onShow(name)` runs each time a tab is shown ("world", "mission", "run"). */
export function setUpTabs(onShow) {
  const tabs = [...document.querySelectorAll('[role="tab"]')];
  const nameOf = (tab) => tab.id.replace(/^tab-/, "");

  function show(tab, focus) {
    for (const other of tabs) {
      const selected = other === tab;
      other.setAttribute("aria-selected", String(selected));
      other.tabIndex = selected ? 0 : -1;
      document.getElementById(other.getAttribute("aria-controls")).hidden = !selected;
    }
    if (focus) tab.focus();
    if (location.hash !== `#${nameOf(tab)}`) history.replaceState(null, "", `#${nameOf(tab)}`);
    onShow(nameOf(tab));
  }

  tabs.forEach((tab, index) => {
    tab.addEventListener("click", () => show(tab, false));
    tab.addEventListener("keydown", (event) => {
      const moves = { ArrowRight: index + 1, ArrowLeft: index - 1, Home: 0, End: tabs.length - 1 };
      if (!(event.key in moves)) return;
      event.preventDefault();
      show(tabs[(moves[event.key] + tabs.length) % tabs.length], true);
    });
  });
  const initial = tabs.find((tab) => `#${nameOf(tab)}` === location.hash) || tabs[0];
  show(initial, false);
  return { show: (name) => show(tabs.find((tab) => nameOf(tab) === name), false) };
}
