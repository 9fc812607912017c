// Wide tables scroll sideways inside their `.table-wrap` (on a phone). While one does, its box
// becomes a named, focusable region, so that keyboard users can scroll it with the arrow keys
// (WCAG 2.1.1); a box that fits stays a plain box, without a tab stop of its own. Every page
// loads this module (layout.html); the region takes its table's name (aria-labelledby).

function update(wrap) {
  const table = wrap.querySelector("table");
  const scrolls = wrap.scrollWidth > wrap.clientWidth;
  if (scrolls === wrap.hasAttribute("tabindex")) return;
  if (scrolls) {
    wrap.setAttribute("role", "region");
    wrap.setAttribute("tabindex", "0");
    if (table?.hasAttribute("aria-labelledby")) wrap.setAttribute("aria-labelledby", table.getAttribute("aria-labelledby"));
  } else {
    ["role", "tabindex", "aria-labelledby"].forEach((name) => wrap.removeAttribute(name));
  }
}

// A box scrolls when it narrows or when its table widens (new rows): watch both.
const observer = new ResizeObserver((entries) => {
  entries.forEach((entry) => update(entry.target.closest(".table-wrap")));
});
document.querySelectorAll(".table-wrap").forEach((wrap) => {
  observer.observe(wrap);
  const table = wrap.querySelector("table");
  if (table) observer.observe(table);
});
