"""One fact: the student guide installs the package with the line GET /api/package prints (its
extras are the route's EXTRAS), then adds the extras the guide itself uses."""
from __future__ import annotations

import re

from league.server.api.routes.package import EXTRAS
from league.server.package import DISTRIBUTION

from ..layout import REPO

INSTALL = re.compile(r'^pip install "(?P<name>[\w-]+)\[(?P<extras>[\w,]+)\] @ (?P<url>\S+)"$', re.M)


def test_the_guide_installs_the_package_with_the_line_the_server_prints():
    guide = (REPO / "docs" / "STUDENT_GUIDE.md").read_text()
    installs = [match.groupdict() for match in INSTALL.finditer(guide)]
    assert len(installs) == 2, installs
    served, added = installs
    assert (served["name"], served["extras"]) == (DISTRIBUTION, EXTRAS)
    assert served["url"].startswith("http://SERVER/api/package/") and added["url"] == served["url"]
    assert not set(added["extras"].split(",")) & set(EXTRAS.split(","))  # only what the guide adds
