"""Content-addressed store of submitted files: DATA_DIR/blobs/ab/abcdef... (sha256 of the content).

The same file uploaded twice is stored once. Files are written to DATA_DIR/tmp first and moved
into place atomically, so a reader never sees half a file.
"""
from __future__ import annotations

import hashlib
import os
import tempfile
import time
from pathlib import Path
from typing import BinaryIO

CHUNK = 1024 * 1024
SWEEP_GRACE_S = 600.0  # a file younger than this may be an upload whose row is not committed yet


class FileTooLarge(Exception):
    def __init__(self, limit: int):
        super().__init__(f"file too large: the limit is {limit / (1024 * 1024):g} MB")
        self.limit = limit


class EmptyFile(Exception):
    pass


class BlobStore:
    def __init__(self, root: Path):
        self.root = Path(root)
        self.blobs = self.root / "blobs"
        self.tmp = self.root / "tmp"

    def ensure(self) -> None:
        """The store's directories, the server's alone: no other user of the machine reads a model."""
        for directory in (self.root, self.blobs, self.tmp):
            directory.mkdir(parents=True, exist_ok=True)
            os.chmod(directory, 0o700)

    def path(self, sha256: str) -> Path:
        return self.blobs / sha256[:2] / sha256

    def save(self, source: BinaryIO, *, max_bytes: int) -> tuple[str, int]:
        """Copy a stream into the store, hashing and counting as it goes; return (sha256, size)."""
        digest, size = hashlib.sha256(), 0
        handle, tmp_name = tempfile.mkstemp(dir=self.tmp, prefix="upload-")
        try:
            with os.fdopen(handle, "wb") as out:
                while chunk := source.read(CHUNK):
                    size += len(chunk)
                    if size > max_bytes:
                        raise FileTooLarge(max_bytes)
                    digest.update(chunk)
                    out.write(chunk)
            if size == 0:
                raise EmptyFile()
            sha256 = digest.hexdigest()
            self._move_into_place(Path(tmp_name), sha256)
            return sha256, size
        finally:
            Path(tmp_name).unlink(missing_ok=True)

    def _move_into_place(self, tmp_path: Path, sha256: str) -> None:
        target = self.path(sha256)
        if target.exists():
            return  # already stored: content-addressed, identical bytes
        target.parent.mkdir(exist_ok=True)
        os.chmod(tmp_path, 0o600)
        os.replace(tmp_path, target)

    def write_verified(self, sha256: str, data: bytes) -> Path:
        """Store bytes fetched from elsewhere (the database) after checking they are what was asked for."""
        if hashlib.sha256(data).hexdigest() != sha256:
            raise ValueError(f"stored bytes do not match their sha256 {sha256}")
        handle, tmp_name = tempfile.mkstemp(dir=self.tmp, prefix="fetch-")
        try:
            with os.fdopen(handle, "wb") as out:
                out.write(data)
            self._move_into_place(Path(tmp_name), sha256)
        finally:
            Path(tmp_name).unlink(missing_ok=True)
        return self.path(sha256)

    def remove(self, sha256: str) -> None:
        """Forget a file (its bytes are no longer kept: a refused or rejected upload)."""
        self.path(sha256).unlink(missing_ok=True)

    def sweep(self, kept: set[str], older_than_s: float = SWEEP_GRACE_S) -> list[str]:
        """Remove the files whose digest is not in `kept` (the database's record), but for the newest
        (an upload is stored before its row is committed); return them."""
        cutoff = time.time() - older_than_s
        removed = [path.name for path in self.blobs.glob("??/*") if path.name not in kept
                   and path.stat().st_mtime < cutoff]
        for sha256 in removed:
            self.remove(sha256)
        return removed

    def add_file(self, path: Path) -> tuple[str, int]:
        with open(path, "rb") as source:
            return self.save(source, max_bytes=2**62)
