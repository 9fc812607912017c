"""docker-compose.yml and the Dockerfile: no engine runs here, so their structure is checked, and the
commands they run are the ones the other tests start by hand (`league serve`, `league worker`)."""
from __future__ import annotations

import json
from pathlib import Path

import yaml

from league.cli import build_parser

REPO = Path(__file__).resolve().parents[2]


def compose() -> dict:
    return yaml.safe_load((REPO / "docker-compose.yml").read_text())


def test_compose_has_the_api_a_scalable_worker_postgres_and_redis():
    services = compose()["services"]
    assert set(services) == {"api", "worker", "postgres", "redis"}
    for name in ("api", "worker"):
        environment = services[name]["environment"]
        assert environment["LEAGUE_DATABASE_URL"].startswith("postgresql+psycopg://league:league@postgres:5432/")
        assert environment["LEAGUE_QUEUE_URL"] == "redis://redis:6379/0"
        assert set(services[name]["depends_on"]) == {"postgres", "redis"}
    assert "ports" not in services["worker"] and "container_name" not in services["worker"]  # --scale worker=N


def test_compose_and_dockerfile_commands_are_league_commands():
    parser = build_parser()
    services = compose()["services"]
    dockerfile = (REPO / "Dockerfile").read_text()
    cmd = next(line for line in dockerfile.splitlines() if line.startswith("CMD "))
    commands = [services["api"]["command"], services["worker"]["command"], json.loads(cmd[len("CMD "):])]
    for command in commands:
        assert command[0] == "league"
        args = parser.parse_args(command[1:])
        assert args.run.__module__ == "league.server.cli"


def test_the_workers_of_one_host_share_a_cpu_slots_volume():
    compose_file = compose()
    worker = compose_file["services"]["worker"]
    slots_dir = worker["environment"]["LEAGUE_CPU_SLOTS_DIR"]
    volume = next(mount.split(":")[0] for mount in worker["volumes"] if mount.split(":")[1] == slots_dir)
    assert volume in compose_file["volumes"]  # a named volume: every replica on the host mounts the same one
