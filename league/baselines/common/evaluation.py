"""The evaluation hook of a run: `metrics_run` of the deterministic actor, and which one is best."""
from __future__ import annotations

from torch import nn

from league.agents import torch_module_agent
from league.evaluation import metrics_run

FINAL_EVAL_SEED = 0  # the final 100-episode evaluation uses `league evaluate`'s default tracks


def evaluate(policy: nn.Module, obs_dim: int, episodes: int, seed: int, **env_options) -> dict:
    """`league.evaluation.metrics_run` of the deterministic actor; the summary figures."""
    was_training = policy.training
    agent = torch_module_agent(policy, obs_dim=obs_dim, name="policy")
    result = metrics_run(agent, episodes=episodes, seed=seed, **env_options)
    policy.train(was_training)
    return {"completed": result.completed, "episodes": result.episodes_total, "mean_return": result.mean_return,
            "mean_steps": result.mean_steps, "mean_speed": result.mean_speed, "outcomes": result.outcome_counts()}


def eval_key(result: dict) -> tuple:
    """Which periodic evaluation is best: the highest racing score, completed fraction × mean
    speed (a league race is won by finishing, fast), then the higher mean return.

    Ranking by completed laps alone keeps the slowest cautious actor; by speed alone, a reckless one.
    """
    return result["completed"] / result["episodes"] * result["mean_speed"], result["mean_return"]

