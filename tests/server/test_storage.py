"""The content-addressed store."""
from __future__ import annotations

import hashlib
import io

import pytest

from league.server.storage import BlobStore, EmptyFile, FileTooLarge


@pytest.fixture
def store(tmp_path):
    store = BlobStore(tmp_path / "data")
    store.ensure()
    return store


def test_same_content_is_stored_once_under_its_sha256(store):
    data = b"model bytes" * 1000
    first = store.save(io.BytesIO(data), max_bytes=10**6)
    second = store.save(io.BytesIO(data), max_bytes=10**6)
    digest = hashlib.sha256(data).hexdigest()
    assert first == second == (digest, len(data))
    assert store.path(digest).read_bytes() == data
    assert [p.name for p in store.blobs.rglob("*") if p.is_file()] == [digest]
    assert list(store.tmp.iterdir()) == []


def test_limit_and_empty_files_leave_nothing_behind(store):
    with pytest.raises(FileTooLarge, match="file too large: the limit is 0.00390625 MB"):
        store.save(io.BytesIO(b"x" * 4097), max_bytes=4096)
    with pytest.raises(EmptyFile):
        store.save(io.BytesIO(b""), max_bytes=4096)
    assert list(store.tmp.iterdir()) == [] and [p for p in store.blobs.rglob("*") if p.is_file()] == []


def test_fetched_bytes_are_checked_against_their_name(store):
    data = b"weights"
    digest = hashlib.sha256(data).hexdigest()
    assert store.write_verified(digest, data).read_bytes() == data
    with pytest.raises(ValueError, match="do not match"):
        store.write_verified("0" * 64, data)
