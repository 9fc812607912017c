"""The API's routers (league/server/api/routes/__init__.py): one module per resource, every one listed in
`api_router`, and no API route served from anywhere else."""
from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

from fastapi.routing import APIRoute

from league.server.api import routes
from league.server.app import create_app
from league.server.core.config import Settings


def module_routes() -> set[tuple[str, str]]:
    """(method, /api path) of every route of every module in league/server/api/routes/."""
    found = set()
    for module in pkgutil.iter_modules(routes.__path__):
        router = importlib.import_module(f"{routes.__name__}.{module.name}").router
        found |= {(method, "/api" + route.path) for route in router.routes if isinstance(route, APIRoute)
                  for method in route.methods}
    return found


def test_every_api_route_is_one_of_the_listed_routers(tmp_path):
    app = create_app(Settings(data_dir=tmp_path))
    served = {(method.upper(), path) for path, operations in app.openapi()["paths"].items()
              if path.startswith("/api/") for method in operations}
    assert served == module_routes()
    assert ("POST", "/api/tracks/geometry") in served


def test_routes_reach_the_services_through_dependencies_only():
    """league.server.api.deps is the one reader of app.state (the league's services, the response cache)."""
    readers = [path.name for path in Path(routes.__file__).parent.glob("*.py") if "app.state" in path.read_text()]
    assert readers == []
