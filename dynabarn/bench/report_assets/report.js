// The sweep report's one behaviour: sort every planner's grid of worlds x trials.
// Rows carry their keys as data attributes; ties keep the world order.
(function () {
  "use strict";
  const select = document.getElementById("sort");
  if (!select) { return; }
  const descending = { measured: true, successes: false, difficulty: false, id: false };
  function sortAll(key) {
    document.querySelectorAll("table.cells tbody").forEach(function (body) {
      const rows = Array.from(body.rows);
      rows.sort(function (a, b) {
        const x = parseFloat(a.dataset[key]);
        const y = parseFloat(b.dataset[key]);
        const order = descending[key] ? y - x : x - y;
        return order !== 0 ? order : parseFloat(a.dataset.id) - parseFloat(b.dataset.id);
      });
      rows.forEach(function (row) { body.appendChild(row); });
    });
  }
  select.addEventListener("change", function () { sortAll(select.value); });
})();
