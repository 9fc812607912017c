"""Network namespaces for tests: another host (a worker, a hostile client) in one command.

`ip` runs iproute2; `unused_prefix` finds a 10.x.y.0/24 no interface uses; `other_host` is a
network namespace joined to this host by a veth pair. Needs root and `ip netns`; skips otherwise.
"""
from __future__ import annotations

import contextlib
import os
import random
import shutil
import subprocess
import uuid
from collections.abc import Iterator
from dataclasses import dataclass

import pytest


def ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], check=True, capture_output=True, text=True, timeout=30)


def require_namespaces() -> None:
    if os.geteuid() != 0:
        pytest.skip("network namespaces need root")
    if shutil.which("ip") is None:
        pytest.skip("`ip` not found: apt-get install iproute2")


def unused_prefix() -> str:
    taken = ip("-4", "-o", "addr").stdout
    for _ in range(100):
        prefix = f"10.{random.randrange(200, 250)}.{random.randrange(256)}"
        if f" {prefix}." not in taken:
            return prefix
    pytest.skip("no free 10.x.y.0/24 for the test network")


@dataclass(frozen=True)
class OtherHost:
    namespace: str
    address: str  # the other host's
    local_address: str  # this host's end of the link

    def run_in(self) -> tuple[str, ...]:
        """The prefix of a command run on the other host."""
        return ("ip", "netns", "exec", self.namespace)


@contextlib.contextmanager
def other_host() -> Iterator[OtherHost]:
    """A network namespace linked to this host by a veth pair (PREFIX.1 here, PREFIX.2 there); removed
    at the end, whatever happened."""
    require_namespaces()
    tag, prefix = uuid.uuid4().hex[:6], unused_prefix()
    host = OtherHost(f"league-{tag}", f"{prefix}.2", f"{prefix}.1")
    try:
        ip("netns", "add", host.namespace)
    except subprocess.CalledProcessError as error:
        pytest.skip(f"`ip netns add` is not permitted here: {error.stderr.strip()}")
    try:
        ip("link", "add", f"lg{tag}h", "type", "veth", "peer", "name", f"lg{tag}n", "netns", host.namespace)
        ip("addr", "add", f"{host.local_address}/24", "dev", f"lg{tag}h")
        ip("link", "set", f"lg{tag}h", "up")
        ip("-n", host.namespace, "addr", "add", f"{host.address}/24", "dev", f"lg{tag}n")
        ip("-n", host.namespace, "link", "set", f"lg{tag}n", "up")
        ip("-n", host.namespace, "link", "set", "lo", "up")
        yield host
    finally:  # deleting the namespace deletes the veth pair
        subprocess.run(["ip", "netns", "del", host.namespace], capture_output=True, timeout=30)
