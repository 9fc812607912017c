"""axe-core's WCAG 2.1 A and AA rules on a page in a real browser, at a desktop's and a phone's width
(test_accessibility.py, test_integrity_page.py).

axe-core comes from PyPI's `axe-playwright-python` (pinned in pyproject.toml's `web-test` extra;
it bundles axe-core 4.12.1, whose licence is MPL-2.0). Audit injects its `axe.min.js` into the
page through the browser's debugging protocol: the app never serves it.
"""
from __future__ import annotations

import json

import pytest

axe_playwright = pytest.importorskip("axe_playwright_python.base",
                                     reason="the accessibility tests need `pip install axe-playwright-python`")

AXE_TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa"]
# Every rule of those WCAG levels, the experimental ones too (they include "label in name", 2.5.3).
RUN_AXE = """async (tags) => {
  const experimental = axe.getRules(tags).filter((rule) => rule.tags.includes("experimental"));
  const results = await axe.run(document, {
    runOnly: {type: "tag", values: tags}, resultTypes: ["violations"],
    rules: Object.fromEntries(experimental.map((rule) => [rule.ruleId, {enabled: true}])),
  });
  return results.violations.map((v) => `${v.id} (${v.help}): ` +
    v.nodes.map((node) => `${node.target.join(" ")} [${node.failureSummary.replaceAll("\\n", " ")}]`).join("; "));
}"""
NEXT_FRAMES = "() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))"
PHONE = {"width": 320, "height": 640}  # WCAG 1.4.10 reflow: 320 CSS px
DESKTOP = {"width": 1280, "height": 900}


def axe_violations(page) -> list[str]:
    if not page.evaluate("typeof axe !== 'undefined'"):
        page.evaluate(axe_playwright.AXE_SCRIPT)
    return page.evaluate(RUN_AXE, AXE_TAGS)


class Audit:
    """axe's violations on each state of a page, at a desktop's and a phone's width."""

    def __init__(self, web):
        self.web = web
        self.found: dict[str, list[str]] = {}

    def check(self, state: str, widths=(DESKTOP, PHONE)) -> None:
        for size in widths:
            self.web.page.set_viewport_size(size)
            self.web.page.evaluate(NEXT_FRAMES)  # the resize observers have run
            violations = axe_violations(self.web.page)
            if violations:
                self.found[f"{state} at {size['width']} px"] = violations
        self.web.page.set_viewport_size(DESKTOP)

    def assert_clean(self) -> None:
        assert not self.found, json.dumps(self.found, indent=1, ensure_ascii=False)
