"""Each baseline trains, checkpoints, exports; the same seed gives the same first updates;
exported actors act as the torch actor does."""
import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnxruntime")

from league.agents import load_agent  # noqa: E402
from league.baselines import ALGORITHMS, load_algorithm  # noqa: E402
from league.baselines.common.export import export_policy, probe_observations  # noqa: E402
from league.baselines.common.networks import ObservationNormalizer  # noqa: E402
from league.baselines.common.run import Run  # noqa: E402

pytestmark = pytest.mark.slow  # trainings and `league` subprocesses: the full suite's tier

# a few hundred steps, learning from step 100, no long evaluations
TINY = {"steps": 300, "learning_starts": 100, "eval_every": 0, "final_eval_episodes": 0, "checkpoint_every": 0,
        "log_every": 20}
TINY_PPO = {"steps": 768, "envs": 2, "num_steps": 64, "eval_every": 0, "final_eval_episodes": 0,
            "checkpoint_every": 0, "log_every": 1}


def tiny_args(algorithm, **overrides):
    module = load_algorithm(algorithm)
    return module, module.Args(**{**(TINY_PPO if algorithm == "ppo" else TINY), **overrides})


def cli(*args, timeout=120):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MPLBACKEND", "LEAGUE_DEBUG")}
    return subprocess.run([sys.executable, "-m", "league.cli", *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=timeout)


@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_trains_a_few_hundred_steps_and_exports(algorithm, tmp_path):
    """CleanRL's smoke test: the command trains, logs, evaluates, draws its curves; the export loads."""
    out = tmp_path / "run"
    steps = ["--steps", 768, "--envs", 2, "--num-steps", 128] if algorithm == "ppo" else \
        ["--steps", 300, "--learning-starts", 100, "--log-every", 50]
    result = cli("train", algorithm, *steps, "--eval-every", 256, "--eval-episodes", 2, "--final-eval-episodes", 2,
                 "--out", out, "--no-progress")
    assert result.returncode == 0, result.stderr
    assert "completed" in result.stdout
    for name in ("config.json", "charts.csv", "losses.csv", "eval.csv", "checkpoint.pt", "policy_final.pt",
                 "policy_best.pt", "summary.json", "curves.png"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == (768 if algorithm == "ppo" else 300)
    assert summary["final_eval"]["final"]["episodes"] == 2
    exported = tmp_path / f"{algorithm}.onnx"
    result = cli("export", out, "--format", "onnx", "--out", exported)
    assert result.returncode == 0, result.stderr
    agent = load_agent(exported)
    assert agent.obs_dim == json.loads((out / "config.json").read_text())["obs_dim"]
    assert agent(probe_observations(agent.obs_dim, batch=8)).shape == (8, 2)


def train_in_process(algorithm, folder, **overrides):
    module, args = tiny_args(algorithm, **overrides)
    run = Run(folder, algorithm, args, progress=False, tensorboard=False)
    module.train(args, run)
    run.close()
    with open(folder / "losses.csv") as handle:
        rows = [{k: v for k, v in row.items() if k not in ("wall_time", "SPS")} for row in csv.DictReader(handle)]
    return rows, torch.load(folder / "policy_final.pt", weights_only=True)


@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_same_seed_same_first_updates(algorithm, tmp_path):
    """As Stable-Baselines3's test_deterministic: two trainings with one seed match exactly."""
    rows_a, weights_a = train_in_process(algorithm, tmp_path / "a", seed=3)
    rows_b, weights_b = train_in_process(algorithm, tmp_path / "b", seed=3)
    rows_c, weights_c = train_in_process(algorithm, tmp_path / "c", seed=4)
    assert len(rows_a) >= 4 and rows_a == rows_b
    assert all(torch.equal(weights_a[k], weights_b[k]) for k in weights_a)
    assert rows_a != rows_c
    assert not all(torch.equal(weights_a[k], weights_c[k]) for k in weights_a)


@pytest.mark.parametrize("algorithm", ["ddpg", "dsac"])
def test_learning_rates_end_at_their_final_fraction(algorithm, tmp_path):
    """DDPG and DSAC decay their rates linearly (by default to 0 and to a tenth); the run's last
    checkpoint holds the rates of its last update."""
    assert load_algorithm(algorithm).Args().lr_final_fraction == {"ddpg": 0.0, "dsac": 0.1}[algorithm]
    train_in_process(algorithm, tmp_path, lr_final_fraction=0.25)
    _, args = tiny_args(algorithm)
    agent = torch.load(tmp_path / "checkpoint.pt", weights_only=True)["algorithm"]["agent"]
    initial = ({"q_optimizer": args.learning_rate, "actor_optimizer": args.learning_rate} if algorithm == "ddpg" else
               {"q_optimizer": args.q_lr, "actor_optimizer": args.policy_lr, "a_optimizer": args.q_lr})
    for name, lr in initial.items():
        assert agent[name]["param_groups"][0]["lr"] == pytest.approx(0.25 * lr), name


def export_random_actor(algorithm, fmt, tmp_path):
    """The algorithm's deterministic actor with large random weights and fitted observation statistics, exported."""
    module, args = tiny_args(algorithm)
    torch.manual_seed(0)
    policy = module.make_policy(args)
    with torch.no_grad():  # larger weights than at initialisation: actions away from 0, some saturated
        for param in policy.parameters():
            param.normal_(0.0, 0.5)
    for module in policy.modules():  # and fitted observation statistics, which are exported too
        if isinstance(module, ObservationNormalizer):
            module.fit(probe_observations(20, batch=64, seed=1))
    return policy, export_policy(policy, tmp_path / f"actor{'.onnx' if fmt == 'onnx' else '.pt'}", fmt, obs_dim=20)


@pytest.fixture(scope="module")
def exported_actor(tmp_path_factory):
    """`export_random_actor`, once per algorithm and format for the tests that read the file."""
    cache = {}

    def get(algorithm, fmt):
        if (algorithm, fmt) not in cache:
            cache[algorithm, fmt] = export_random_actor(algorithm, fmt, tmp_path_factory.mktemp(f"{algorithm}-{fmt}"))
        return cache[algorithm, fmt]
    return get


@pytest.mark.filterwarnings("ignore:`torch.jit.load` is deprecated:DeprecationWarning")
@pytest.mark.parametrize("fmt", ["onnx", "torchscript"])
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_exported_actor_acts_as_the_torch_actor(algorithm, fmt, exported_actor):
    policy, path = exported_actor(algorithm, fmt)
    agent = load_agent(path)
    assert agent.kind == fmt and agent.obs_dim == 20
    obs = probe_observations(20, batch=200)
    with torch.no_grad():
        expected = policy(torch.from_numpy(obs)).numpy()
    assert np.abs(expected).max() > 0.5  # a meaningful comparison, not of near-zero actions
    np.testing.assert_allclose(agent(obs), expected, atol=1e-5, rtol=0)


@pytest.mark.filterwarnings("ignore:`torch.jit.load` is deprecated:DeprecationWarning")
@pytest.mark.parametrize("fmt", ["onnx", "torchscript"])
@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_the_server_accepts_the_exported_actor(algorithm, fmt, exported_actor):
    """The league's static checks (allow-listed ONNX operators / TorchScript ops) pass."""
    pytest.importorskip("onnx", reason="the onnx extra is not installed")
    from league.validation import checks as model_checks

    _, path = exported_actor(algorithm, fmt)
    if fmt == "onnx":
        model_checks.check_onnx(path)
    else:
        model_checks.check_torchscript_archive(path)
        model_checks.check_torchscript_graph(torch.jit.load(str(path)))


def test_deterministic_actor_ignores_exploration_noise(tmp_path):
    """The exported SAC actor is the mean action: the same observation always gives the same action."""
    module, args = tiny_args("sac")
    policy = module.make_policy(args)
    obs = torch.from_numpy(probe_observations(20, batch=16))
    with torch.no_grad():
        assert torch.equal(policy(obs), policy(obs))
        mean, _ = policy.actor(obs)
        assert torch.equal(policy(obs), torch.tanh(mean))
