"""The API's routers, one module per resource, all listed here: `api_router` is what create_app
serves under /api (their body limits: league.server.api.limits, set in create_app)."""
from __future__ import annotations

from fastapi import APIRouter

from league.server.api.routes import (
    assignments, audit, championships, evaluations, grades, health, integrity, jobs, leaderboard, package, privacy,
    races, submissions, tracks, users,
)

api_router = APIRouter()
for module in (health, audit, users, assignments, grades, submissions, evaluations, privacy, jobs, races,
               championships, leaderboard, package, integrity, tracks):
    api_router.include_router(module.router)
