"""docker-compose.yml and the Dockerfile: no engine runs here, so their structure is checked, and the
commands they run are the ones the other tests start by hand (`league serve`, `league worker`)."""
from __future__ import annotations

import json
from pathlib import Path

import yaml
from sqlalchemy.engine import make_url

from league.cli import build_parser
from league.server.config import Settings

REPO = Path(__file__).resolve().parents[2]


def compose() -> dict:
    return yaml.safe_load((REPO / "docker-compose.yml").read_text())


def league_settings(service: dict) -> Settings:
    """The settings a service's container starts with (its LEAGUE_* variables, nothing else)."""
    environment = service["environment"]
    unknown = [key for key in environment if key.removeprefix("LEAGUE_").lower() not in Settings.model_fields]
    assert not unknown, f"variables no setting reads (misspelt?): {unknown}"
    return Settings(_env_file=None, **{key.removeprefix("LEAGUE_").lower(): value
                                       for key, value in environment.items()})


def test_the_api_and_scalable_workers_share_the_database_and_queue_of_compose_services():
    """What a deployment needs: every LEAGUE_ variable is a real setting, the API and the workers
    use one PostgreSQL database and one Redis queue, served by services they wait for, and the
    worker can be scaled (no fixed port or name)."""
    services = compose()["services"]
    api, worker = league_settings(services["api"]), league_settings(services["worker"])
    assert (api.resolved_database_url, api.resolved_queue_url) == (worker.resolved_database_url,
                                                                   worker.resolved_queue_url)
    database, queue = make_url(api.resolved_database_url), make_url(api.resolved_queue_url)
    assert database.get_backend_name() == "postgresql" and queue.drivername == "redis"
    for name in ("api", "worker"):
        waits_for = set(services[name]["depends_on"])
        assert {database.host, queue.host} <= waits_for <= set(services), name
        assert all(services[name]["depends_on"][host]["condition"] == "service_healthy" for host in waits_for)
    assert "ports" not in services["worker"] and "container_name" not in services["worker"]


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
