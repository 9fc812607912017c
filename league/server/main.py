"""`uvicorn league.server.main:app` (Docker image): the app built from the environment's settings.

`league serve` builds its own app with an embedded worker instead.
"""
from league.server.app import create_app

app = create_app()
