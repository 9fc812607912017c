"""The sandbox process on its own: deadlines, restarts, isolation, logs."""
from __future__ import annotations

import functools
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from league import testing as mf
from league.agents import AgentError, dry_run_observations
from league.evaluation import metrics_run
from league.server.sandbox.agent import SandboxedAgent
from league.server.sandbox.log import LogBuffer
from league.server.sandbox.process import ForkServer, Isolation, IsolationUnavailable, _child_environment
from league.server.sandbox.validation import validate_model
from league.validation.limits import SandboxLimits

FAST = SandboxLimits(first_call_allowance_s=0.3, load_cpu_s=20, max_restarts=1)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("sandbox-models")
    return {"good": mf.onnx_mlp(d / "mlp.onnx"), "slow": mf.onnx_slow(d / "slow.onnx"),
            "quick": mf.onnx_slow(d / "quick.onnx", layers=40)}


def obs(batch: int = 1) -> np.ndarray:
    return dry_run_observations(5, batch)


def test_sandboxed_agent_answers_like_the_model(files):
    from league.agents import load_agent

    with SandboxedAgent(files["good"], "onnx", FAST) as agent:
        assert (agent.obs_dim, agent.name) == (5, "submission")
        np.testing.assert_array_equal(agent(obs(3)), load_agent(files["good"])(obs(3)))


@pytest.mark.parametrize("make, kind, reason", [
    (functools.partial(mf.onnx_nan_when_straight, threshold=-0.5), "onnx", "the model returned NaN or infinite"),
    (mf.torchscript_raises_when_close, "torchscript", "the model raised"),
])
def test_a_model_failing_on_some_observations_fails_only_those_episodes_as_in_process(tmp_path, make, kind, reason):
    """The sandbox's answer "the model failed on these observations" is isolable: metrics_run asks
    again row by row, so the server's figures equal `league evaluate`'s, episode by episode."""
    from league.agents import load_agent

    model = make(tmp_path / f"flaky{'.onnx' if kind == 'onnx' else '.pt'}")
    alone = metrics_run(load_agent(model), episodes=12, seed=3)
    with SandboxedAgent(model, kind, FAST) as agent:
        boxed = metrics_run(agent, episodes=12, seed=3)
        assert agent.restarts == 0
    failed = [e for e in boxed.episodes if e.outcome == "dnf"]
    assert 0 < len(failed) < 12 and all(e.reason.startswith(reason) for e in failed), boxed.episodes
    assert len({e.steps for e in failed}) > 1  # not all at once, on the first batch that failed
    assert [e.to_dict() for e in boxed.episodes] == [e.to_dict() for e in alone.episodes]


def test_a_call_over_its_cpu_budget_is_a_dnf_then_the_sandbox_restarts_then_gives_up(files):
    with SandboxedAgent(files["slow"], "onnx", FAST) as agent:
        with pytest.raises(AgentError, match=r"used more than its 20 ms of CPU per observation"):
            for _ in range(100):  # the 300 ms allowance is spent, then the budget bites
                agent(obs())
        with pytest.raises(AgentError, match=r"ms of CPU per observation"):
            for _ in range(100):
                agent(obs())  # a fresh sandbox (restart 1 of 1), a fresh allowance
        assert agent.restarts == 1
        with pytest.raises(AgentError, match=r"the agent was stopped after 2 failures; last: the model used more"):
            agent(obs())


def test_the_run_budget_ends_a_run_that_uses_too_much_cpu_in_all(files):
    limits = SandboxLimits(run_cpu_s=0.05, first_call_allowance_s=0.3, load_cpu_s=20)
    with SandboxedAgent(files["quick"], "onnx", limits) as agent:
        with pytest.raises(AgentError, match=r"more than 0.05 s of CPU time in this run"):
            for _ in range(1000):
                agent(obs())
        assert agent.cpu_used >= 0.05
        with pytest.raises(AgentError, match=r"in this run"):  # and it stays ended
            agent(obs())


# An evaluation pinned to one CPU: it loads the model, lowers its sandbox's scheduling weight (the
# sandbox shares its fork server's session, so its autogroup), says "loaded", waits for a line on
# stdin, then runs and prints the episodes and the largest CPU time per observation of a call.
_PINNED_EVALUATION = """
import json, os, sys
from league.evaluation import metrics_run
from league.server.sandbox.agent import SandboxedAgent
from league.server.sandbox.child import set_autogroup_nice
from league.validation.limits import SandboxLimits
model, cpu_per_observation, cpu = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
os.sched_setaffinity(0, {cpu})
limits = SandboxLimits(step_deadline_s=cpu_per_observation, first_call_allowance_s=0.0, load_cpu_s=20,
                       max_restarts=0)
with SandboxedAgent(model, "onnx", limits) as agent:
    set_autogroup_nice(10, agent._process.proc.pid)
    with open(f"/proc/{agent._process.proc.pid}/autogroup") as autogroup:
        assert autogroup.read().split()[-1] == "10"
    print("loaded", flush=True)
    sys.stdin.readline()
    result = metrics_run(agent, episodes=2, seed=4, max_episode_steps=40)
    print(json.dumps({"episodes": [e.to_dict() for e in result.episodes],
                      "max_cpu": max(agent.cpu_per_observation)}))
"""
_BURNER = "import os, sys\nos.sched_setaffinity(0, {int(sys.argv[1])})\nwhile True:\n    pass\n"


def _pinned_evaluation(model: Path, cpu_per_observation: float, cpu: int, burners: int = 0) -> dict:
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[3])}
    run = subprocess.Popen([sys.executable, "-c", _PINNED_EVALUATION, str(model), str(cpu_per_observation), str(cpu)],
                           stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    started = [subprocess.Popen([sys.executable, "-c", _BURNER, str(cpu)], start_new_session=True)
               for _ in range(burners)]  # each its own session, so its own autogroup: a full share each
    try:
        assert run.stdout.readline().strip() == "loaded"
        output, _ = run.communicate("go\n", timeout=300)
    finally:
        for burner in started:
            burner.kill()
            burner.wait()
    assert run.returncode == 0, output
    return json.loads(output)


@pytest.mark.long
def test_a_busy_machine_changes_no_result_and_the_budget_is_on_the_cpu_clock(files):
    """The same evaluation on a quiet CPU and on one shared with three CPU burners, with a budget of
    3x the largest CPU time per observation seen when quiet: the same episodes, none a DNF. (The
    sandbox gets a quarter of the CPU or less when busy, so a call takes over 4x its CPU time on
    the wall clock: a wall-clock budget makes DNFs of them.)"""
    cpu = max(os.sched_getaffinity(0))
    quiet = _pinned_evaluation(files["quick"], 1.0, cpu)
    busy = _pinned_evaluation(files["quick"], 3 * quiet["max_cpu"], cpu, burners=3)
    assert not any(episode["outcome"] == "dnf" for episode in quiet["episodes"])
    assert busy["episodes"] == quiet["episodes"]


# A heat's sandboxes, started at once by a job's thread (at the job's nice): prints each one's
# scheduling group's nice value.
_HEAT_OF_SANDBOXES = """
import contextlib, os, sys
from league.server.sandbox.agent import SandboxedAgent
from league.validation.limits import SandboxLimits
os.nice(10)
with contextlib.ExitStack() as stack:
    agents = [stack.enter_context(SandboxedAgent(sys.argv[1], "onnx", SandboxLimits())) for _ in range(10)]
    for agent in agents:
        with open(f"/proc/{agent._process.proc.pid}/autogroup") as autogroup:
            print(autogroup.read().split()[-1], flush=True)
"""


def test_every_sandbox_of_a_heat_yields_the_cpu_to_the_api(files):
    """Ten sandboxes started at once by a thread at nice 10 all run in a scheduling group (autogroup)
    at nice 10. (Without CAP_SYS_ADMIN the kernel changes one group's nice per 0.1 s on the whole
    machine: ten sandboxes setting a group each of their own left most of them at nice 0, as an
    equal of the API. tests/system/test_unprivileged_sandbox.py runs this as an ordinary user.)"""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[3])}
    run = subprocess.run([sys.executable, "-c", _HEAT_OF_SANDBOXES, str(files["good"])], capture_output=True,
                         text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert run.stdout.split() == ["10"] * 10


def test_validation_measures_the_model_speed(files):
    report = validate_model(files["good"], "onnx", FAST)
    assert report.ok and report.obs_dim == 5 and report.error is None
    assert report.cpu_ms_per_observation > 0  # ok means it is within the budget: no clock of ours asserted here


def test_the_sandbox_cannot_reach_the_network():
    probe = ("import socket, sys\n"
             "from league.server.sandbox.child import isolate_network\n"
             "mode = isolate_network()\n"
             "print(mode)\n"
             "try:\n"
             "    socket.create_connection(('127.0.0.1', 5432), timeout=2)\n"
             "    print('connected')\n"
             "except OSError as error:\n"
             "    print('refused', error.errno)\n")
    env = {**_child_environment(Path(tempfile.gettempdir())),  # one thread, as sandboxes (a user namespace needs it)
           "PYTHONPATH": str(Path(__file__).resolve().parents[3])}
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, env=env)
    mode, outcome = result.stdout.split("\n", 1)
    if mode == "unavailable":
        pytest.skip("no network namespaces here (not root, no user namespaces)")
    assert outcome.startswith("refused"), result.stdout + result.stderr


def test_the_child_holds_nothing_of_the_parent(files, tmp_path):
    secret = open(tmp_path / "league.db", "w")  # an open file of the worker, as a database would be
    try:
        with SandboxedAgent(files["good"], "onnx", FAST) as agent:
            process = agent._process
            workdir = process.workdir
            assert (workdir / "model.onnx").read_bytes() == files["good"].read_bytes()  # a copy, in its own dir
            assert Path(f"/proc/{process.proc.pid}/cwd").resolve() == workdir
            targets = [os.readlink(f"/proc/{process.proc.pid}/fd/{fd}")
                       for fd in os.listdir(f"/proc/{process.proc.pid}/fd")]
            environment = Path(f"/proc/{process.proc.pid}/environ").read_bytes().split(b"\0")
            assert not (workdir / ".cache").exists()  # onnxruntime's telemetry is off: no offline cache
        assert not any(str(tmp_path) in target for target in targets)
        assert not any(target.startswith("socket:") for target in targets)  # not the fork server's control socket
        assert all(t == os.devnull or t.startswith("pipe:") or t.startswith(str(workdir)) for t in targets), targets
        assert not any(name.lower().startswith((b"http_proxy", b"https_proxy", b"league_")) for name in environment)
        assert not workdir.exists()
    finally:
        secret.close()


def test_log_buffer_keeps_the_head_and_the_tail():
    log = LogBuffer(limit=100)
    log.write(b"H" * 25)
    log.write(b"x" * 1000)
    log.write(b"TAIL")
    text = log.text()
    assert text.startswith("H" * 25) and text.endswith("TAIL")
    assert "[... 929 bytes cut ...]" in text
    assert len(text) < 140


# --------------------------------------------------------------------------- the fork server


def alive(pid: int) -> bool:
    """Running, not a zombie."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def wait_gone(pids: list[int], timeout: float = 10) -> list[int]:
    deadline = time.monotonic() + timeout
    while any(alive(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    return [pid for pid in pids if alive(pid)]


def test_sandboxes_are_forked_from_a_single_threaded_server_that_reaps_them(files):
    agents = [SandboxedAgent(files["good"], "onnx", FAST) for _ in range(3)]
    server = ForkServer.of_this_thread(".onnx")
    try:
        assert len(os.listdir(f"/proc/{server.proc.pid}/task")) == 1  # forking a threaded process is unsafe
        assert [a._process.proc.pid in children(server.proc.pid) for a in agents] == [True] * 3
        assert all(a(obs()).shape == (1, 2) for a in agents)
    finally:
        for agent in agents:
            agent.close()
    assert children(server.proc.pid) == []  # closed sandboxes were waited for: no zombies left


def children(pid: int) -> list[int]:
    return [int(child) for child in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]


def test_a_crash_is_reported_with_its_signal_and_the_agent_restarts(files):
    with SandboxedAgent(files["good"], "onnx", FAST) as agent:
        first = agent._process.proc.pid
        os.kill(first, signal.SIGSEGV)
        with pytest.raises(AgentError, match=r"the sandbox process crashed \(SIGSEGV\); see the log"):
            agent(obs())
        assert agent(obs()).shape == (1, 2) and agent._process.proc.pid != first and agent.restarts == 1


def test_sandboxes_end_with_the_thread_that_started_them(files):
    """The fork server is tied to its thread (a worker's job thread): when it ends, so do the
    server and its sandboxes; an agent used afterwards fails once, then starts a new sandbox."""
    started = {}

    def start():
        started["agent"] = SandboxedAgent(files["good"], "onnx", FAST)
        started["server"] = ForkServer.of_this_thread(".onnx").proc.pid

    thread = threading.Thread(target=start)
    thread.start()
    thread.join()
    agent = started["agent"]
    try:
        assert wait_gone([started["server"], agent._process.proc.pid]) == []
        with pytest.raises(AgentError, match=r"crashed \(SIGKILL\)"):
            agent(obs())
        assert agent(obs()).shape == (1, 2) and agent.restarts == 1  # in this thread's server
    finally:
        agent.close()


def test_nothing_outlives_a_killed_worker(files, tmp_path):
    script = ("import os, signal, sys\n"
              "from league.server.sandbox.agent import SandboxedAgent\n"
              "from league.validation.limits import SandboxLimits\n"
              "from league.server.sandbox.process import ForkServer\n"
              "agent = SandboxedAgent(sys.argv[1], 'onnx', SandboxLimits(load_cpu_s=20))\n"
              "print(ForkServer.of_this_thread('.onnx').proc.pid, agent._process.proc.pid, flush=True)\n"
              "os.kill(os.getpid(), signal.SIGKILL)\n")
    result = subprocess.run([sys.executable, "-c", script, str(files["good"])], capture_output=True, text=True,
                            timeout=60, env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[3])})
    assert result.returncode == -signal.SIGKILL, result.stderr
    pids = [int(pid) for pid in result.stdout.split()]
    assert len(pids) == 2 and wait_gone(pids) == []


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs")
def test_sandboxes_start_on_the_cpus_their_thread_may_use_now(files):
    cpus = sorted(os.sched_getaffinity(0))
    seen = []

    def start_two():  # one fork server for both (one thread), moved between them
        os.sched_setaffinity(0, {cpus[1]})
        with SandboxedAgent(files["good"], "onnx", FAST) as agent:
            seen.append(os.sched_getaffinity(agent._process.proc.pid))
        os.sched_setaffinity(0, set(cpus))
        with SandboxedAgent(files["good"], "onnx", FAST) as agent:
            seen.append(os.sched_getaffinity(agent._process.proc.pid))
            agent(obs())

    thread = threading.Thread(target=start_two)
    thread.start()
    thread.join()
    assert seen == [{cpus[1]}, set(cpus)]


def test_without_landlock_and_seccomp_no_model_runs_unless_allowed():
    partial = Isolation("namespace", "the server's user", landlock=0, seccomp=True, uid_base=0)
    assert partial.missing == ["Landlock, which keeps sandboxes from files their user may read (Linux 5.13 or "
                               "later, with landlock in its lsm= boot parameter)"]
    with pytest.raises(IsolationUnavailable, match=r"not run here: the sandbox is Landlock ABI 0, .*; NOT fully "
                                                   r"isolated, missing Landlock, .*"
                                                   r"LEAGUE_SANDBOX_REQUIRE_ISOLATION=false"):
        partial.check(SandboxLimits())
    assert partial.check(SandboxLimits(require_isolation=False)) is partial
    broken = Isolation("unknown", "unknown", 0, False, 0, problem="ModuleNotFoundError: No module named 'torch'")
    assert broken.describe() == "NOT isolated: ModuleNotFoundError: No module named 'torch'"
    assert broken.missing == ["a sandbox that starts (the probe sandbox failed: ModuleNotFoundError: No module "
                              "named 'torch')"]


def test_a_model_that_fails_to_load_leaves_no_directory(tmp_path):
    before = set(Path(tempfile.gettempdir()).glob("league-sandbox-*"))
    report = validate_model(mf.random_bytes(tmp_path / "random.onnx"), "onnx", FAST)
    assert not report.ok
    assert set(Path(tempfile.gettempdir()).glob("league-sandbox-*")) <= before
