"""The API's routers, one per resource; the submissions router gets the upload size limit."""
from __future__ import annotations

from fastapi import APIRouter

from league.server.api.routes import (
    championships, evaluations, health, jobs, leaderboard, races, submissions, users,
)

api_router = APIRouter()
for module in (health, users, evaluations, jobs, races, championships, leaderboard):
    api_router.include_router(module.router)

upload_router = submissions.router  # included by create_app with max_body_size from the settings
