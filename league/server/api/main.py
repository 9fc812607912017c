"""The API's routers, one per resource (their body limits: league.server.api.limits, set in create_app)."""
from __future__ import annotations

from fastapi import APIRouter

from league.server.api.routes import (
    assignments, championships, evaluations, grades, health, jobs, leaderboard, package, races, submissions, users,
)

api_router = APIRouter()
for module in (health, users, assignments, grades, submissions, evaluations, jobs, races, championships, leaderboard,
               package):
    api_router.include_router(module.router)
