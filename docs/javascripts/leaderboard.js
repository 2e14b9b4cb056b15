// The leaderboard's tables sort by any column: click a heading (again: the other way).
// Cells carry the number they sort by (data-sort); text sorts as text. Material for MkDocs
// swaps pages without reloading (document$), so the tables are found on every page shown.
(function () {
  "use strict";
  function value(cell) {
    const raw = cell.dataset.sort !== undefined ? cell.dataset.sort : cell.textContent.trim();
    const number = parseFloat(raw);
    return isNaN(number) ? raw.toLowerCase() : number;
  }
  function sortable(table) {
    if (table.dataset.ready) { return; }
    table.dataset.ready = "1";
    table.querySelectorAll("thead th").forEach(function (th, column) {
      th.tabIndex = 0;
      th.title = "sort by " + th.textContent;
      function sort() {
        const body = table.tBodies[0];
        const descending = th.getAttribute("aria-sort") !== "descending";
        table.querySelectorAll("thead th").forEach(function (other) { other.removeAttribute("aria-sort"); });
        th.setAttribute("aria-sort", descending ? "descending" : "ascending");
        const rows = Array.from(body.rows);
        rows.sort(function (a, b) {
          const x = value(a.cells[column]);
          const y = value(b.cells[column]);
          const order = x < y ? -1 : x > y ? 1 : 0;
          return descending ? -order : order;
        });
        rows.forEach(function (row) { body.appendChild(row); });
      }
      th.addEventListener("click", sort);
      th.addEventListener("keydown", function (e) { if (e.key === "Enter") { sort(); } });
    });
  }
  function all() { document.querySelectorAll("table.sortable").forEach(sortable); }
  if (typeof window.document$ !== "undefined") { window.document$.subscribe(all); } else { all(); }
  document.addEventListener("DOMContentLoaded", all);
})();
