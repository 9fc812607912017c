"""API tokens: random secrets shown once, stored as their sha256 (a leaked database reveals no token)."""
from __future__ import annotations

import hashlib
import secrets

TOKEN_PREFIX = "lg_"  # recognisable in logs and secret scanners


def new_token() -> str:
    return TOKEN_PREFIX + secrets.token_urlsafe(32)


def hash_token(token: str) -> str:
    return hashlib.sha256(token.encode()).hexdigest()
