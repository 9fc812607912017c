"""The thesis' interface (Galletti, sections 3.4-3.6), for the course's existing material.

``Racer``, ``newrun`` and ``metrics_run`` keep the names and arguments of the original
``tracks.py`` but are thin layers over ``league.MicroRacerEnv`` and ``league.evaluation``.
They accept the toolkit's agents and also what the thesis passed: any model that takes a batch
of states and returns the action as its (first) output - a Keras model, a torch module, a
function, an object with ``predict`` - or the path of an ONNX / TorchScript file.
"""
from __future__ import annotations

import os
import warnings
from typing import Any, Sequence

import numpy as np

from league import evaluation
from league.agents import as_agent
from league.env import MicroRacerEnv


class Racer:
    """The thesis' environment object: ``reset() -> state``, ``step(action) -> (state, reward, done)``.

    ``Racer(obstacles=False, turn_limit=False, chicanes=False, low_speed_termination=False)``
    turns the optional parts off. The state is the compact observation
    ``[direction, left, max, right, speed]`` (float32, shape (5,)); ``done`` is true when the
    episode ended for any reason (lap, crash, time limit). Unlike the original, a done step
    returns the last valid state rather than a one-element array. ``info`` holds the last step's
    details (outcome, progress, time, distance, speed). ``seed`` seeds the first ``reset``.
    """

    def __init__(self, tstep: float = 0.04, obstacles: bool = True, turn_limit: bool = True, chicanes: bool = True,
                 low_speed_termination: bool = True, seed: int | None = None, **env_options):
        self.env = MicroRacerEnv(tstep=tstep, obstacles=obstacles, turn_limit=turn_limit, chicanes=chicanes,
                                 low_speed_termination=low_speed_termination, observation="compact", **env_options)
        self._seed = seed
        self.info: dict = {}

    def reset(self) -> np.ndarray:
        state, self.info = self.env.reset(seed=self._seed)
        self._seed = None  # later resets continue the seeded stream
        return state

    def step(self, action) -> tuple[np.ndarray, float, bool]:
        state, reward, terminated, truncated, self.info = self.env.step(np.asarray(action, dtype=np.float32).reshape(2))
        return state, reward, bool(terminated or truncated)

    @property
    def track(self):
        return self.env.track


def newrun(actors: Sequence[Any], obstacles: bool = True, turn_limit: bool = True, chicanes: bool = True,
           low_speed_termination: bool = True, *, seed: int | None = None, names: Sequence[str] | None = None,
           show: bool = True, save: str | os.PathLike | None = None, **env_options) -> evaluation.RaceResult:
    """The thesis' race: all actors on one track, printed classification and an animation.

    ``seed`` (random if omitted) fixes the track; ``save="race.gif"`` writes the animation;
    ``show`` opens a window when a display is available. Returns the RaceResult.
    """
    from league import render

    if seed is None:
        seed = int(np.random.SeedSequence().generate_state(1)[0])
    agents = [as_agent(actor) for actor in actors]
    result = evaluation.race(agents, seed=seed, names=names, obstacles=obstacles, turn_limit=turn_limit,
                             chicanes=chicanes, low_speed_termination=low_speed_termination, **env_options)
    print(f"race on seed {seed}")
    print(result.table())
    if save is not None:
        render.animate_replay(result.replay, save=save)
    if show:
        try:
            render.require_display()
        except render.RenderError as error:
            warnings.warn(f"{error}; the race is in the returned result", stacklevel=2)
        else:
            render.animate_replay(result.replay, show=True)
    return result


def metrics_run(actor: Any, runs_num: int = 100, obstacles: bool = True, turn_limit: bool = True,
                chicanes: bool = True, low_speed_termination: bool = True, *, seed: int = 0, verbose: bool = True,
                **env_options) -> evaluation.MetricsResult:
    """The thesis' evaluation run: ``runs_num`` episodes, printed as they end, then the totals.

    The same as ``league.evaluation.metrics_run(as_agent(actor), episodes=runs_num, seed=seed, ...)``.
    """

    def report(i: int, episode: evaluation.EpisodeResult) -> None:
        print(f"episode {i}: steps {episode.steps}, return {episode.episode_return:.3f}, "
              f"mean speed {episode.mean_speed:.3f}, {evaluation.OUTCOME_TEXT[episode.outcome]}")

    result = evaluation.metrics_run(as_agent(actor), episodes=runs_num, seed=seed, on_episode=report if verbose else None,
                                    obstacles=obstacles, turn_limit=turn_limit, chicanes=chicanes,
                                    low_speed_termination=low_speed_termination, **env_options)
    if verbose:
        print(f"completed {result.completed} / {result.episodes_total}, mean return {result.mean_return:.3f}, "
              f"mean steps {result.mean_steps:.1f}, mean speed {result.mean_speed:.3f}")
    return result


__all__ = ["Racer", "as_agent", "metrics_run", "newrun"]
