"""docker-compose.yml, the Dockerfile and deploy/nginx.conf. No container engine runs here, so what
they say is checked against what they name: their commands are the CLI's (each one's --help runs),
their LEAGUE_* variables are settings, their images are pinned; the worker's capabilities are given
to a real sandbox (setpriv), and a real nginx with the proxy's configuration fronts a real
`league serve`."""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import ssl
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import httpx
import pytest
import yaml
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from sqlalchemy.engine import make_url

from league.cli import build_parser
from league.server.core.config import Settings
from league.server.jobs.alive import alive_file, stale_reason

from ..layout import REPO
from ..server.api_calls import wait_for
from ..server.backends import fresh_backend
from .servers import embedded_worker, free_port, freeze, make_server

PINNED_IMAGE = re.compile(r"^[\w./-]+(:\d+(\.\d+)+[\w.-]*|@sha256:[0-9a-f]{64})$")  # a version with a dot, or a digest
PLACEHOLDER = re.compile(r"\$\{(\w+)(:?[?-][^}]*)?\}")  # compose's ${VAR}, ${VAR:?message}, ${VAR:-default}
SECRET_NAME = re.compile(r"PASSWORD|SECRET|TOKEN|KEY", re.I)


def compose() -> dict:
    return yaml.safe_load((REPO / "docker-compose.yml").read_text())


def services() -> dict[str, dict]:
    return compose()["services"]


def interpolated(value: str) -> str:
    """A compose value with its ${...} filled in as from a .env (a password of hex digits)."""
    return PLACEHOLDER.sub(lambda match: "0123abcd" if SECRET_NAME.search(match[1]) else match[1].lower(), value)


def league_settings(service: dict, secrets: Path | None = None) -> Settings:
    """The settings a service's container starts with (its LEAGUE_* variables, nothing else; its secret
    files, /run/secrets/NAME, read from `secrets`/NAME)."""
    environment = {key: interpolated(str(value)) for key, value in service["environment"].items()
                   if key.startswith("LEAGUE_")}
    for key, value in environment.items():
        if value.startswith("/run/secrets/"):
            assert secrets is not None, f"{key} reads a secret: give the test its directory"
            environment[key] = str(secrets / value.removeprefix("/run/secrets/"))
    unknown = [key for key in environment if key.removeprefix("LEAGUE_").lower() not in Settings.model_fields]
    assert not unknown, f"variables no setting reads (misspelt?): {unknown}"
    return Settings(_env_file=None, **{key.removeprefix("LEAGUE_").lower(): value
                                       for key, value in environment.items()})


def dockerfile() -> str:
    return (REPO / "Dockerfile").read_text()


def league_commands() -> list[list[str]]:
    """Every `league ...` command the compose file and the Dockerfile run, health checks included."""
    found = []
    for service in services().values():
        for command in (service.get("command"), service.get("healthcheck", {}).get("test", [])[1:]):
            if command and command[0] == "league":
                found.append(command)
    cmd = next(line for line in dockerfile().splitlines() if line.startswith("CMD "))
    return found + [json.loads(cmd[len("CMD "):])]


# --------------------------------------------------------------------------- the compose file


def test_the_api_and_scalable_workers_share_the_database_of_a_compose_service(tmp_path):
    """What a deployment needs: every LEAGUE_ variable is a real setting, the API and the workers
    use one PostgreSQL database (also the queue) with the password of the secret file, served by a
    service they wait for, and the worker can be scaled (no fixed port or name)."""
    (tmp_path / "db_password").write_text("0123abcd\n")
    api, worker = (league_settings(services()[name], tmp_path) for name in ("api", "worker"))
    assert api.resolved_database_url == worker.resolved_database_url
    database = make_url(api.resolved_database_url)
    assert database.password == "0123abcd" and database.username == services()["db"]["environment"]["POSTGRES_USER"]
    assert database.get_backend_name() == "postgresql" and database.host in services()
    for name in ("api", "worker"):
        assert services()[name]["depends_on"][database.host]["condition"] == "service_healthy", name
    assert "ports" not in services()["worker"] and "container_name" not in services()["worker"]
    assert "ports" not in services()["api"]  # reached through the proxy only


def test_every_command_is_a_league_command_whose_help_runs():
    parser = build_parser()
    commands = league_commands()
    assert {tuple(command[:2]) for command in commands} >= {("league", "serve"), ("league", "worker")}
    assert ["league", "worker", "--check"] in commands  # the worker's health check
    for command in commands:
        args = parser.parse_args(command[1:])  # its options exist
        assert args.run.__module__ == "league.server.cli"
        shown = subprocess.run([sys.executable, "-m", "league", command[1], "--help"], capture_output=True, text=True,
                               timeout=60, env={**os.environ, "PYTHONPATH": str(REPO)})
        assert shown.returncode == 0 and f"league {command[1]}" in shown.stdout, shown.stderr


def test_every_league_variable_set_or_suggested_is_a_setting():
    suggested = re.findall(r"^#?\s*(LEAGUE_\w+)=", (REPO / ".env.example").read_text(), re.M)
    set_here = [key for service in services().values() for key in service.get("environment", {})
                if key.startswith("LEAGUE_")]
    assert suggested and set_here
    unknown = [key for key in suggested + set_here if key.removeprefix("LEAGUE_").lower() not in Settings.model_fields]
    assert not unknown, f"variables no setting reads (misspelt?): {unknown}"


def test_every_image_is_pinned():
    for name, service in services().items():
        if "build" in service:  # built here: the Dockerfile's base image is the one to pin
            assert ":" in service["image"] and not service["image"].endswith(":latest"), name
        else:
            assert PINNED_IMAGE.match(service["image"]), f"{name}: {service['image']} is not an exact version"
    bases = re.findall(r"^FROM\s+(\S+)", dockerfile(), re.M)
    assert bases and all(PINNED_IMAGE.match(base) for base in bases), bases


def test_every_service_restarts_and_has_a_health_check():
    for name, service in services().items():
        if service.get("profiles"):  # a one-shot that cron runs (the backup): it exits when done
            assert service["restart"] == "no", name
            continue
        assert service.get("restart") in {"always", "unless-stopped", "on-failure"}, name
        test = service.get("healthcheck", {}).get("test")
        assert test and test[0] in {"CMD", "CMD-SHELL"} and len(test) > 1, name
    assert services()["db"]["healthcheck"]["test"][1] == "pg_isready"


def test_what_must_persist_is_on_named_volumes():
    declared = compose()["volumes"]
    mounts = {name: dict(mount.split(":")[1::-1] for mount in service.get("volumes", []))
              for name, service in services().items()}
    assert mounts["db"]["/var/lib/postgresql/data"] in declared  # the league's whole state
    assert mounts["worker"]["/run/league-cpu-slots"] in declared  # every replica on the host mounts the same one
    assert mounts["backup"]["/backups"] in declared
    assert services()["backup"]["command"][:2] == ["league", "backup"] and services()["backup"]["command"][-1] == \
        "/backups"
    assert services()["worker"]["environment"]["LEAGUE_CPU_SLOTS_DIR"] == "/run/league-cpu-slots"


def test_the_database_password_is_a_secret_file_in_no_environment():
    """The password reaches PostgreSQL and the league as a file (a compose secret), never as a variable:
    it is in no container's environment, the sandboxed worker's included, nor in .env or a committed file."""
    text = (REPO / "docker-compose.yml").read_text()
    assert compose()["secrets"]["db_password"]["file"] == "./deploy/secrets/db_password"
    for name, service in services().items():
        environment = {key: str(value) for key, value in service.get("environment", {}).items()}
        for key, value in environment.items():
            if SECRET_NAME.search(key):
                assert key.endswith("_FILE") and value == "/run/secrets/db_password", f"{name}: {key}={value}"
            assert not re.search(r"://[^/@:]+:[^@]+@", value), f"{name}: {key} holds a password"
        if name != "proxy":
            assert "db_password" in service["secrets"], name
    assert "POSTGRES_PASSWORD=" not in (REPO / ".env.example").read_text() and "${POSTGRES_PASSWORD" not in text
    for ignore in (".gitignore", ".dockerignore"):
        ignored = (REPO / ignore).read_text().split()
        assert ".env" in ignored and "deploy/secrets/" in ignored, ignore


def test_every_container_is_bounded_and_its_logs_rotated():
    """Memory, CPU and process limits on every service (a runaway model or a fork bomb in a worker
    takes its container, not the host), and docker's logs rotated by size."""
    for name, service in services().items():
        limits = service["deploy"]["resources"]["limits"]
        assert float(limits["cpus"]) > 0 and re.fullmatch(r"\d+[mg]", str(limits["memory"])), name
        assert 0 < int(limits["pids"]) <= 5000, name
        logging = service["logging"]
        assert logging["driver"] == "json-file" and re.fullmatch(r"\d+m", logging["options"]["max-size"]), name
        assert int(logging["options"]["max-file"]) >= 1, name


@pytest.mark.parametrize("status, healthy", [(200, True), (503, False), (500, False)])
def test_the_api_health_check_fails_on_503(tmp_path, status, healthy):
    """The compose health check's own command, run against a server answering `status` (on a free port
    in place of 8000): a league that answers 503 (no worker alive) is unhealthy."""
    import http.server
    import threading

    class Answer(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(status)
            self.end_headers()

        def log_message(self, *args):
            pass

    server = http.server.HTTPServer(("127.0.0.1", 0), Answer)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        test = services()["api"]["healthcheck"]["test"]
        assert test[:2] == ["CMD", "python"]
        command = [sys.executable, *[part.replace("8000", str(server.server_port)) for part in test[2:]]]
        done = subprocess.run(command, capture_output=True, timeout=30)
    finally:
        server.shutdown()
    assert (done.returncode == 0) == healthy, done.stderr


def test_the_worker_keeps_only_the_capabilities_its_sandboxes_need():
    for name, service in services().items():
        assert "SYS_ADMIN" not in service.get("cap_add", []) and not service.get("privileged"), name
        assert not any("unconfined" in option for option in service.get("security_opt", [])), name
    worker = services()["worker"]
    assert worker["cap_drop"] == ["ALL"] and "no-new-privileges:true" in worker["security_opt"]


SANDBOX_UNDER_CAPABILITIES = """
import json, sys, tempfile
from pathlib import Path
from league.server.sandbox.process import sandbox_isolation
from league.server.sandbox.validation import validate_model
from league.validation.limits import SandboxLimits
isolation = sandbox_isolation()
report = validate_model(Path(sys.argv[1]), "onnx", SandboxLimits())
print(json.dumps({"isolation": isolation.to_dict(), "user": isolation.user, "ok": report.ok, "error": report.error,
                  "left": [str(path) for path in Path(tempfile.gettempdir()).glob("league-*")]}))
"""


def test_with_only_the_workers_capabilities_a_sandbox_is_fully_isolated_and_cleaned_up(tmp_path):
    """A root process given the compose file's cap_add alone (setpriv's bounding set) and no new
    privileges, as the worker's container: the probe sandbox takes a user id of its own, and a
    model is validated, its sandbox killed (KILL) and its directory removed (DAC_OVERRIDE)."""
    if os.geteuid() != 0 or shutil.which("setpriv") is None:
        pytest.skip("needs root and setpriv (util-linux)")
    capabilities = ",".join(f"+{name.lower()}" for name in services()["worker"]["cap_add"])
    tmp = Path(tmp_path / "tmp")
    tmp.mkdir(mode=0o755)
    tmp_path.chmod(0o755)  # sandboxes work in TMPDIR as their own user
    model = REPO / "league" / "baselines" / "agents" / "sac.onnx"
    done = subprocess.run(["setpriv", f"--bounding-set=-all,{capabilities}", "--no-new-privs", sys.executable, "-c",
                           SANDBOX_UNDER_CAPABILITIES, str(model)], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(REPO), "TMPDIR": str(tmp)})
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.splitlines()[-1])
    assert found["isolation"]["full"], found["isolation"]
    assert found["user"].startswith("uid "), found  # its own, not root's (in or out of a user namespace)
    assert found["ok"] and found["error"] is None, found
    assert found["left"] == [], found


# --------------------------------------------------------------------------- the Dockerfile


def test_the_image_installs_the_tested_cpu_build_of_torch():
    install = re.search(r"pip install (torch\S*) --index-url (\S+)", dockerfile())
    assert install and install[2] == "https://download.pytorch.org/whl/cpu"
    pinned = Requirement(install[1])
    assert len(pinned.specifier) == 1 and next(iter(pinned.specifier)).operator == "=="
    version = next(iter(pinned.specifier)).version
    extra = re.search(r'^torch = \["(.*)"\]', (REPO / "pyproject.toml").read_text(), re.M)[1]
    assert Requirement(extra).specifier.contains(version)
    assert f'"torch=={version}"' in (REPO / "README.md").read_text()  # the release the test command installs


def test_the_image_and_the_readmes_install_what_building_the_students_sdist_needs():
    """GET /api/package builds the sdist with setup.py in the server's own environment, with no
    package index (league/server/package.py): every server install documented (the Dockerfile's, the
    READMEs') holds [build-system]'s requirements, but wheel, which only building a wheel asks for.
    tests/system/test_as_documented.py builds it from the README's install."""
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    needed = {canonicalize_name(Requirement(r).name) for r in pyproject["build-system"]["requires"]} - {"wheel"}
    install = re.compile(r'pip install -e "\.\[([\w,]+)\]"')
    texts = [dockerfile(), *(path.read_text() for path in (REPO / "README.md", REPO / "league/server/README.md"))]
    installs = [extras for text in texts for extras in install.findall(text)]
    assert len(installs) >= 3, installs
    for extras in installs:
        optional = pyproject["project"]["optional-dependencies"]
        requirements = pyproject["project"]["dependencies"] + [requirement for extra in extras.split(",")
                                                               for requirement in optional[extra]]
        have = {canonicalize_name(Requirement(requirement).name) for requirement in requirements}
        assert needed <= have, (extras, needed - have)


def test_the_image_runs_as_an_ordinary_user_and_only_the_worker_as_root():
    users = re.findall(r"^USER\s+(\S+)", dockerfile(), re.M)
    assert users and users[-1] not in {"root", "0"}
    assert [name for name, service in services().items() if service.get("user") in {"root", "0"}] == ["worker"]


# --------------------------------------------------------------------------- the worker's health check


@pytest.fixture(scope="module")
def league(tmp_path_factory):
    """A real `league serve` (SQLite, with its worker process)."""
    tmp_path = tmp_path_factory.mktemp("deploy")
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url)
        before = server.command("worker", "--check")
        server.start_api()
        try:
            yield server, before
        finally:
            server.stop_all()


def test_the_worker_health_check_follows_the_workers_passes(league):
    """Unhealthy before the worker's first pass, healthy while it passes, unhealthy once it hangs."""
    server, before = league
    assert before.returncode == 1 and "no worker has reached the database from here yet" in before.stderr
    wait_for(lambda: server.command("worker", "--check").returncode, lambda code: code == 0, timeout=60)
    worker = embedded_worker(server.api)
    freeze(worker)  # hung (a controllable clock: its last pass then set an hour back)
    try:
        alive = alive_file(server.data_dir)
        os.utime(alive, (time.time() - 3600, time.time() - 3600))
        hung = server.command("worker", "--check")
        assert hung.returncode == 1 and "the worker's last pass that reached the database was" in hung.stderr
    finally:
        os.kill(worker, signal.SIGCONT)
    wait_for(lambda: server.command("worker", "--check").returncode, lambda code: code == 0, timeout=60)


def test_a_worker_counts_as_dead_after_three_missed_passes(tmp_path):
    path = alive_file(tmp_path)
    assert "does not exist" in stale_reason(path, 10)
    path.touch()
    beat_at = path.stat().st_mtime
    assert stale_reason(path, 10, now=beat_at + 30) is None
    assert "31 s ago (more than 3 x LEAGUE_REAPER_INTERVAL_S = 30 s" in stale_reason(path, 10, now=beat_at + 31)


# --------------------------------------------------------------------------- the proxy


def proxy_configuration(tmp_path: Path, api_port: int, http_port: int, https_port: int) -> Path:
    """deploy/nginx.conf with this machine's addresses, a certificate made here and a 1 s header
    timeout, included in a main configuration of its own; each replaced line must exist."""
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=league", "-days", "1",
                    "-keyout", str(tmp_path / "league.key"), "-out", str(tmp_path / "league.pem")],
                   check=True, capture_output=True, timeout=60)
    text = (REPO / "deploy" / "nginx.conf").read_text()
    for old, new in [("listen 80;", f"listen 127.0.0.1:{http_port};"),
                     ("listen 443 ssl;", f"listen 127.0.0.1:{https_port} ssl;"),
                     ("http://api:8000", f"http://127.0.0.1:{api_port}"),
                     ("client_header_timeout 10s;", "client_header_timeout 1s;")]:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    (tmp_path / "league.conf").write_text(text.replace("/etc/nginx/certs/", f"{tmp_path}/"))
    main = tmp_path / "nginx.conf"
    main.write_text(f"pid {tmp_path}/nginx.pid; error_log {tmp_path}/error.log;\n"
                    f"events {{}}\nhttp {{ access_log off; include {tmp_path}/league.conf; }}\n")
    return main


def require_nginx() -> None:
    if shutil.which("nginx") is None or shutil.which("openssl") is None:
        pytest.skip("needs nginx and openssl (Debian: apt-get install nginx-light openssl)")


def test_the_proxy_configuration_is_one_nginx_accepts(tmp_path):
    require_nginx()
    main = proxy_configuration(tmp_path, 8000, 8080, 8443)
    checked = subprocess.run(["nginx", "-t", "-p", str(tmp_path), "-c", str(main)], capture_output=True, text=True,
                             timeout=60)
    assert checked.returncode == 0, checked.stderr


@pytest.fixture
def proxy(league, tmp_path):
    require_nginx()
    server, _ = league
    http_port, https_port = free_port(), free_port()
    main = proxy_configuration(tmp_path, server.port, http_port, https_port)
    nginx = subprocess.Popen(["nginx", "-p", str(tmp_path), "-c", str(main), "-g", "daemon off;"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_for(lambda: listening(https_port) or nginx.poll() is not None, bool, timeout=30)
        assert nginx.poll() is None, nginx.stderr.read().decode()
        yield http_port, https_port
    finally:
        nginx.terminate()
        nginx.wait(timeout=30)


def listening(port: int) -> bool:
    with socket.socket() as sock:
        return sock.connect_ex(("127.0.0.1", port)) == 0


def test_nginx_in_front_of_league_serve_answers_over_tls_and_bounds_bodies(league, proxy):
    server, _ = league
    http_port, https_port = proxy
    with httpx.Client(base_url=f"https://127.0.0.1:{https_port}", verify=False, timeout=30) as client:
        health = client.get("/api/health")
        assert health.status_code == httpx.get(f"{server.url}/api/health").status_code == 200
        assert health.json()["status"] == "ok" and health.headers["strict-transport-security"]
        assert "<main" in client.get("/").text
        too_big = client.post("/api/submissions", content=b"\0" * (12 * 1024 * 1024),
                              headers={"Content-Type": "application/octet-stream"})
        assert too_big.status_code == 413  # refused by nginx before the API reads it
    plain = httpx.get(f"http://127.0.0.1:{http_port}/api/health")
    assert plain.status_code == 301 and plain.headers["location"].startswith("https://")
    assert httpx.get(f"http://127.0.0.1:{http_port}/healthz").text == "ok\n"  # the container's health check


def test_nginx_cuts_a_client_whose_request_head_never_ends(proxy):
    http_port, https_port = proxy
    watched = subprocess.run([sys.executable, "-m", "tests.system.slow_clients", "127.0.0.1", str(http_port),
                              "3", "30"],
                             cwd=REPO, capture_output=True, text=True, timeout=120)
    ends = json.loads(watched.stdout.splitlines()[-1])
    assert all(end["end"] != "open" for end in ends), ends
    # over TLS too: the handshake done, half a head, then nothing
    context = ssl.create_default_context()
    context.check_hostname, context.verify_mode = False, ssl.CERT_NONE
    with context.wrap_socket(socket.create_connection(("127.0.0.1", https_port), timeout=30)) as tls:
        tls.sendall(b"GET /api/health HTTP/1.1\r\nHost: league\r\nX-Wait: ")
        assert tls.recv(65536) == b""  # closed by nginx (within 30 s: the socket's own timeout would raise)
