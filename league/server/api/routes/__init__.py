"""The API's routers, one module per resource, all listed here: `api_router` is what create_app
serves under /api (their body limits: league.server.api.limits, set in create_app)."""
from __future__ import annotations

from fastapi import APIRouter

# Each by its full name: `from league.server.api.routes import ...` would be this package importing itself.
import league.server.api.routes.assignments as assignments
import league.server.api.routes.audit as audit
import league.server.api.routes.championships as championships
import league.server.api.routes.evaluations as evaluations
import league.server.api.routes.grades as grades
import league.server.api.routes.health as health
import league.server.api.routes.integrity as integrity
import league.server.api.routes.jobs as jobs
import league.server.api.routes.leaderboard as leaderboard
import league.server.api.routes.package as package
import league.server.api.routes.privacy as privacy
import league.server.api.routes.races as races
import league.server.api.routes.submissions as submissions
import league.server.api.routes.tracks as tracks
import league.server.api.routes.users as users

api_router = APIRouter()
for module in (health, audit, users, assignments, grades, submissions, evaluations, privacy, jobs, races,
               championships, leaderboard, package, integrity, tracks):
    api_router.include_router(module.router)
