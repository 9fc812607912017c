// A table sorted by clicking (or pressing Enter on) a column header. Each numeric column says,
// under its name and as part of the same button, which way is better ("↑ better": higher is
// better); a first click sorts best first.

import { element } from "./dom.js";

/**
 * columns: [{key, label, value(row) -> sortable value, render(row) -> Node|string,
 *            better: "higher"|"lower" (optional), numeric (bool)}]
 * options: {rowKey(row), isOwn(row), apart(row): shown after the others (class "apart"), whatever the
 *           sort (e.g. results that do not rank), emptyText, sort: {key, descending}}
 */
export class SortableTable {
  constructor(table, columns, { rowKey, isOwn = () => false, apart = () => false, emptyText = "Nothing yet.", sort } = {}) {
    this.table = table;
    this.columns = columns;
    this.rowKey = rowKey;
    this.isOwn = isOwn;
    this.apart = apart;
    this.emptyText = emptyText;
    this.sort = sort || { key: columns[0].key, descending: false };
    this.rows = [];
    this.head = table.createTHead();
    this.body = table.tBodies[0] || table.createTBody();
    this.renderHead();
  }

  update(rows) {
    this.rows = rows;
    this.renderBody();
  }

  renderHead() {
    const row = element("tr");
    for (const column of this.columns) {
      const th = element("th", { attrs: { scope: "col" }, className: column.numeric ? "num" : "" });
      const button = element("button", { className: "sort-button", attrs: { type: "button" } },
        element("span", { text: column.label }),
        element("span", { className: "sort-mark", attrs: { "aria-hidden": "true" } }),
        column.better ? betterHint(column.better) : null);
      button.addEventListener("click", () => this.sortBy(column));
      th.append(button);
      column.th = th;
      row.append(th);
    }
    this.head.replaceChildren(row);
    this.markSort();
  }

  sortBy(column) {
    if (this.sort.key === column.key) {
      this.sort = { key: column.key, descending: !this.sort.descending };
    } else {
      this.sort = { key: column.key, descending: column.better === "higher" };
    }
    this.markSort();
    this.renderBody();
  }

  markSort() {
    for (const column of this.columns) {
      const active = column.key === this.sort.key;
      column.th.setAttribute("aria-sort", active ? (this.sort.descending ? "descending" : "ascending") : "none");
      column.th.querySelector(".sort-mark").textContent = active ? (this.sort.descending ? "▼" : "▲") : "";
    }
  }

  sortedRows() {
    const column = this.columns.find((c) => c.key === this.sort.key);
    const value = column.value || ((row) => row[column.key]);
    const sign = this.sort.descending ? -1 : 1;
    return [...this.rows].sort((a, b) => {
      if (this.apart(a) !== this.apart(b)) return this.apart(a) ? 1 : -1;
      const x = value(a);
      const y = value(b);
      if (x === y) return 0;
      if (x === null || x === undefined) return 1; // missing values last, either way
      if (y === null || y === undefined) return -1;
      return (typeof x === "string" ? x.localeCompare(y) : x - y) * sign;
    });
  }

  renderBody() {
    if (!this.rows.length) {
      const cell = element("td", { text: this.emptyText, className: "muted", attrs: { colspan: this.columns.length } });
      this.body.replaceChildren(element("tr", {}, cell));
      return;
    }
    this.body.replaceChildren(...this.sortedRows().map((row) => {
      const tr = element("tr", { attrs: { "data-key": this.rowKey ? this.rowKey(row) : null } });
      if (this.isOwn(row)) tr.classList.add("own");
      if (this.apart(row)) tr.classList.add("apart");
      for (const column of this.columns) {
        const content = column.render ? column.render(row) : row[column.key];
        tr.append(element("td", { className: column.numeric ? "num" : "" },
          content instanceof Node ? content : document.createTextNode(content ?? "–")));
      }
      return tr;
    }));
  }
}

function betterHint(better) {
  const higher = better === "higher";
  return element("span", { className: "better", attrs: { title: higher ? "higher is better" : "lower is better" } },
    element("span", { text: higher ? "↑ better" : "↓ better", attrs: { "aria-hidden": "true" } }),
    element("span", { className: "visually-hidden", text: higher ? "(higher is better)" : "(lower is better)" }));
}
