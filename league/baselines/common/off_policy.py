"""The off-policy training loop that TD3, DDPG, DDPG with parameter noise, SAC and DSAC share (as
Stable-Baselines3's ``OffPolicyAlgorithm``): act, store the transitions, one gradient update per
transition collected, evaluate and checkpoint on the run's schedule.

An algorithm provides an `OffPolicyLearner`: its networks, how it acts, its updates and what it
logs beside the losses. The schedule of the updates is the loop's: the critics every step, the
actor every ``policy_frequency`` steps, then `after_update` (SAC's target networks).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from torch import nn

from league.baselines.common.args import CommonArgs, obs_dim_of
from league.baselines.common.buffers import ReplayBuffer
from league.baselines.common.cars import make_cars
from league.baselines.common.networks import anneal_learning_rates
from league.baselines.common.run import Run
from league.baselines.common.seeding import seed_everything

ACT_DIM = 2  # [acceleration, turn]


class OffPolicyLearner:
    """What the loop asks of an algorithm; the defaults are those of an algorithm without the hook."""

    actor: nn.Module
    optimizers: list  # annealed together (--lr-final-fraction)

    def act(self, obs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Exploration actions for a batch of observations (`rng`: the loop's, for action noise)."""
        raise NotImplementedError

    def update_critics(self, data) -> dict:
        raise NotImplementedError

    def update_actor(self, data) -> dict:
        raise NotImplementedError

    def after_update(self) -> None:
        """After each gradient step's updates."""

    def episode_ended(self) -> None:
        """After a step in which an episode ended (parameter noise changes per episode)."""

    def fit_normalizers(self, observations: np.ndarray) -> None:
        raise NotImplementedError

    def logged(self) -> dict:
        """Values written beside the losses."""
        return {}

    def policy(self) -> nn.Module:
        """What is evaluated and exported: the deterministic actor."""
        return self.actor

    def state_dict(self) -> dict:
        raise NotImplementedError

    def load_state_dict(self, state: dict) -> None:
        raise NotImplementedError


def train(args: CommonArgs, run: Run, make: Callable[[CommonArgs], OffPolicyLearner]) -> dict:
    """Train the learner `make(args)` builds for ``args.steps`` transitions, resuming from the run's
    last checkpoint when asked; returns the run's summary."""
    seed_everything(args.seed)
    obs_dim = obs_dim_of(args)
    agent = make(args)
    rb = ReplayBuffer(args.buffer_size, obs_dim, ACT_DIM, seed=args.seed)
    action_rng = np.random.default_rng(args.seed)  # random actions, then exploration noise
    global_step = 0
    if run.resume:
        global_step, state = run.load_checkpoint()
        agent.load_state_dict(state["agent"])
        rb.load_state_dict(state["rb"])
        action_rng.bit_generator.state = state["action_rng"]
    cars = make_cars(args, seed_offset=global_step)
    obs = cars.reset()
    run.open_progress(args.steps, global_step)
    losses: dict = {}

    def state() -> dict:
        return {"agent": agent.state_dict(), "rb": rb.state_dict(), "action_rng": action_rng.bit_generator.state}

    while global_step < args.steps:
        if global_step < args.learning_starts:
            actions = action_rng.uniform(-1, 1, (args.envs, ACT_DIM)).astype(np.float32)
        else:
            actions = agent.act(obs, action_rng)
        step = cars.step(actions)
        # Only a crash ends the return: the finish line is an arbitrary cut of a road that goes
        # on, so the target bootstraps through it, as through a time limit (Pardo et al. 2018).
        rb.add(obs, actions, step.rewards, step.next_obs, step.terminated & ~step.finished)
        obs = cars.obs.copy()
        for _ in range(args.envs):  # one gradient update per transition collected
            global_step += 1
            if global_step == args.learning_starts and args.normalize_obs:
                agent.fit_normalizers(rb.observations[:rb.size])
            if global_step > args.learning_starts:
                anneal_learning_rates(agent.optimizers, global_step, args.steps, args.lr_final_fraction)
                data = rb.sample(args.batch_size)
                losses = losses | agent.update_critics(data)
                if global_step % args.policy_frequency == 0:
                    losses |= agent.update_actor(data)
                agent.after_update()
        episodes = cars.pop_episodes()
        if episodes:
            agent.episode_ended()
        run.record(global_step, episodes)
        if losses and global_step % args.log_every < args.envs:
            run.log_losses(global_step, **{k: float(v) for k, v in losses.items()}, **agent.logged())
        if run.evaluation_due(global_step):
            run.evaluate(global_step, agent.policy())
        if run.checkpoint_due(global_step):
            run.save_checkpoint(global_step, state())
    return run.finish(global_step, agent.policy(), state())
