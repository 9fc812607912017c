// "Previous / Page 2 of 5 / Next" for the API's paginated lists ({items, total}, ?page=&size=).

import { element } from "./dom.js";

export class Pager {
  constructor(container, { size = 50, label, onChange }) {
    this.container = container;
    this.size = size;
    this.page = 1;
    this.total = 0;
    this.onChange = onChange;
    this.previous = element("button", { className: "secondary small", text: "Previous", attrs: { type: "button", "aria-label": `Previous page of ${label}` } });
    this.next = element("button", { className: "secondary small", text: "Next", attrs: { type: "button", "aria-label": `Next page of ${label}` } });
    this.where = element("span");
    this.previous.addEventListener("click", () => this.go(this.page - 1));
    this.next.addEventListener("click", () => this.go(this.page + 1));
    container.append(this.previous, this.where, this.next);
    container.hidden = true;
  }

  get pages() {
    return Math.max(1, Math.ceil(this.total / this.size));
  }

  query() {
    return `page=${this.page}&size=${this.size}`;
  }

  update(total) {
    this.total = total || 0;
    this.container.hidden = this.pages <= 1;
    this.where.textContent = `Page ${this.page} of ${this.pages}`;
    this.previous.disabled = this.page <= 1;
    this.next.disabled = this.page >= this.pages;
  }

  go(page) {
    this.page = Math.min(Math.max(page, 1), this.pages);
    this.onChange();
  }
}
