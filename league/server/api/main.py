"""The API's routers, one per resource (their body limits: league.server.api.limits, set in create_app)."""
from __future__ import annotations

from fastapi import APIRouter

from league.server.api.routes import (
    assignments, audit, championships, evaluations, grades, health, integrity, jobs, leaderboard, package, privacy,
    races, submissions, users,
)

api_router = APIRouter()
for module in (health, audit, users, assignments, grades, submissions, evaluations, privacy, jobs, races,
               championships, leaderboard, package, integrity):
    api_router.include_router(module.router)
