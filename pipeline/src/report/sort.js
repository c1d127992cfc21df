// A batch page's task table sorts by the column clicked (numbers as numbers), again to reverse.
"use strict";
(function () {
  const table = document.getElementById("tasks");
  const header = table.rows[0];
  Array.from(header.cells).forEach((cell, column) => {
    cell.style.cursor = "pointer";
    cell.addEventListener("click", () => {
      const rows = Array.from(table.rows).slice(1);
      const key = (row) => row.cells[column].textContent;
      const ascending = table.dataset.sorted !== String(column);
      rows.sort((a, b) => {
        const [x, y] = [key(a), key(b)];
        const [p, q] = [parseFloat(x), parseFloat(y)];
        const order = !isNaN(p) && !isNaN(q) ? p - q : x.localeCompare(y);
        return ascending ? order : -order;
      });
      rows.forEach((row) => table.tBodies[0].appendChild(row));
      table.dataset.sorted = ascending ? String(column) : "";
    });
  });
})();
