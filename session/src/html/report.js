// rtconf report: sortable and filterable tables, a count of the listed cases checked against the
// summary the page was written from, and (with #selftest in the address) a check of the sort and
// the filter whose result is written into the page for a headless browser to read.
(function () {
  "use strict";
  var root = document.documentElement;

  function cellValue(row, index, type) {
    var cell = row.cells[index];
    var text = cell ? (cell.getAttribute("data-value") || cell.textContent) : "";
    if (type === "num") {
      var n = parseFloat(text);
      return isNaN(n) ? -Infinity : n;
    }
    return text.toLowerCase();
  }

  function sortTable(table, index, descending) {
    var head = table.tHead.rows[0].cells[index];
    var type = head.getAttribute("data-sort");
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = cellValue(a, index, type), y = cellValue(b, index, type);
      var c = x < y ? -1 : x > y ? 1 : 0;
      return descending ? -c : c;
    });
    rows.forEach(function (r) { body.appendChild(r); });
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th) {
      th.removeAttribute("aria-sort");
    });
    head.setAttribute("aria-sort", descending ? "descending" : "ascending");
  }

  function makeSortable(table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, index) {
      if (!th.hasAttribute("data-sort")) return;
      th.addEventListener("click", function () {
        sortTable(table, index, th.getAttribute("aria-sort") === "ascending");
      });
    });
  }

  // Shows the rows whose text holds every word of the query and, when a status is chosen, of it.
  function filterTable(table, query, status) {
    var words = query.toLowerCase().split(/\s+/).filter(Boolean);
    var shown = 0;
    Array.prototype.forEach.call(table.tBodies[0].rows, function (row) {
      var text = row.textContent.toLowerCase();
      var ok = words.every(function (w) { return text.indexOf(w) >= 0; }) &&
        (!status || row.getAttribute("data-status") === status);
      row.classList.toggle("hidden", !ok);
      if (ok) shown += 1;
    });
    var count = document.getElementById(table.id + "-shown");
    if (count) count.textContent = String(shown);
    return shown;
  }

  function wireFilter(tableId) {
    var table = document.getElementById(tableId);
    if (!table) return;
    makeSortable(table);
    var input = document.getElementById(tableId + "-filter");
    var select = document.getElementById(tableId + "-status");
    var apply = function () {
      filterTable(table, input ? input.value : "", select ? select.value : "");
    };
    if (input) input.addEventListener("input", apply);
    if (select) select.addEventListener("change", apply);
    apply();
  }

  // The listed cases per status against the summary's counts.
  function checkCounts() {
    var rows = document.querySelectorAll("#case-table tbody tr");
    var counted = {};
    Array.prototype.forEach.call(rows, function (r) {
      var s = r.getAttribute("data-status");
      counted[s] = (counted[s] || 0) + 1;
    });
    var mismatches = [];
    Array.prototype.forEach.call(document.querySelectorAll("[data-listed-status]"), function (cell) {
      var s = cell.getAttribute("data-listed-status");
      var want = parseInt(cell.textContent, 10);
      if ((counted[s] || 0) !== want) mismatches.push(s + ": " + (counted[s] || 0) + " listed, " + want + " counted");
    });
    root.setAttribute("data-listed", JSON.stringify(counted));
    root.setAttribute("data-consistent", mismatches.length ? "no: " + mismatches.join("; ") : "yes");
  }

  function selfTest() {
    var table = document.getElementById("vuid-table");
    if (!table || table.tBodies[0].rows.length === 0) return "ok (no VUID rows)";
    var casesColumn = 1;
    sortTable(table, casesColumn, true);
    var values = Array.prototype.map.call(table.tBodies[0].rows, function (r) {
      return cellValue(r, casesColumn, "num");
    });
    for (var i = 1; i < values.length; i++) {
      if (values[i] > values[i - 1]) return "fail: the cases column is not sorted descending";
    }
    var first = table.tBodies[0].rows[0].cells[0].textContent.trim();
    var shown = filterTable(table, first, "");
    var visible = Array.prototype.filter.call(table.tBodies[0].rows, function (r) {
      return !r.classList.contains("hidden");
    });
    if (shown < 1 || visible.length !== shown) return "fail: filtering by " + first + " shows " + shown;
    if (visible.some(function (r) { return r.textContent.indexOf(first) < 0; })) {
      return "fail: a row without " + first + " stayed visible";
    }
    filterTable(table, "", "");
    var all = Array.prototype.filter.call(table.tBodies[0].rows, function (r) {
      return !r.classList.contains("hidden");
    }).length;
    if (all !== table.tBodies[0].rows.length) return "fail: clearing the filter hides rows";
    return "ok";
  }

  // How many of the page's pictures loaded (after the load event).
  window.addEventListener("load", function () {
    var images = document.images;
    var loaded = Array.prototype.filter.call(images, function (i) {
      return i.complete && i.naturalWidth > 0;
    }).length;
    root.setAttribute("data-images", loaded + "/" + images.length);
  });

  wireFilter("vuid-table");
  wireFilter("case-table");
  checkCounts();
  if (location.hash === "#selftest") root.setAttribute("data-selftest", selfTest());
  root.setAttribute("data-ready", "1");
})();
