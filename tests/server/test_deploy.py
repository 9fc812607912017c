"""docker-compose.yml and the Dockerfile: no engine runs here, so their structure is checked, and the
commands they run are the ones the other tests start by hand (`league serve`, `league worker`).
The server README's nginx front is checked by nginx itself, where it is installed."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
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


def test_the_readmes_nginx_front_is_a_configuration_nginx_accepts(tmp_path):
    """The snippet of league/server/README.md, as a file of conf.d, with a certificate made here."""
    if shutil.which("nginx") is None or shutil.which("openssl") is None:
        pytest.skip("needs nginx and openssl (Debian: apt-get install nginx-light openssl)")
    readme = (REPO / "league" / "server" / "README.md").read_text()
    snippet = re.search(r"```nginx\n(.*?)```", readme, re.S).group(1)
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=league", "-days", "1",
                    "-keyout", str(tmp_path / "league.key"), "-out", str(tmp_path / "league.pem")],
                   check=True, capture_output=True, timeout=60)
    (tmp_path / "league.conf").write_text(snippet.replace("/etc/ssl/", f"{tmp_path}/"))
    (tmp_path / "nginx.conf").write_text(f"pid {tmp_path}/nginx.pid; error_log {tmp_path}/error.log;\n"
                                         f"events {{}}\nhttp {{ include {tmp_path}/league.conf; }}\n")
    checked = subprocess.run(["nginx", "-t", "-p", str(tmp_path), "-c", str(tmp_path / "nginx.conf")],
                             capture_output=True, text=True, timeout=60)
    assert checked.returncode == 0, checked.stderr
