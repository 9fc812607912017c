"""Evaluations and races: the one home of the league's scoring logic (CLI and server alike).

`metrics_run` drives one agent through many seeded episodes (SPEC "Evaluation run"), all of
them in lockstep: one agent call per step for every episode still running; `race` puts
several agents on one shared track through the PettingZoo environment and returns the
classification and a compact, versioned replay.
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from league import __version__
from league.agents import Agent, AgentError, as_agent, compact_from_lidar
from league.cars import new_cars, place_car
from league.constants import (
    COMPACT_DIM, FINISHED, LIDAR_DIM, OUTCOME_TEXT, OUTCOMES, PHYSICS_VERSION, RUNNING, TRACK_FORMAT_VERSION,
    observation_name,
)
from league.options import RaceOptions
from league.parallel_env import parallel_env
from league.track import Track, episode_start

LOCKSTEP_EPISODES = 128  # episodes metrics_run advances together; their maps (1.69 MB each) bound its memory
REPLAY_FORMAT = "microracer-replay"
REPLAY_VERSION = 1
# Replay precision: 1e-5 world units is 1 cm; actions are shown with 2 decimals.
DECIMALS = {"x": 5, "y": 5, "heading": 4, "speed": 4, "acc": 3, "turn": 3}


def episode_seeds(seed: int, episodes: int) -> list[int]:
    """Seeds of a run's episodes: ``numpy.random.SeedSequence(seed).generate_state(episodes)``.

    Episode i's seed depends only on (seed, i), never on the episode count, so runs of any
    length with the same seed share their first tracks, and every agent evaluated with the
    same seed meets the same tracks and initial speeds.
    """
    return [int(s) for s in np.random.SeedSequence(seed).generate_state(episodes, dtype=np.uint32)]


def _checked_options(env_options: dict) -> dict:
    if "observation" in env_options:
        raise ValueError(f"the observation follows the agent's obs_dim ({COMPACT_DIM}: compact, {LIDAR_DIM}: lidar); "
                         "do not pass observation=")
    return dict(env_options)


def _full_options(env_options: dict) -> dict:
    """Every environment option with its value (defaults included), for records and re-runs."""
    options = RaceOptions.from_kwargs(**env_options).to_dict()
    options.pop("observation")
    return options


# --------------------------------------------------------------------------- what produced a result


def league_versions() -> dict:
    """What produces results: the simulator (its physics and its track format) and the package."""
    return {"physics": PHYSICS_VERSION, "track_format": TRACK_FORMAT_VERSION, "package": __version__}


def result_key(seed: int, episodes: int, env_options: dict, versions: dict | None = None) -> str:
    """16 hex digits that two evaluations share when their results compare: the same seed,
    episode count and environment options (defaults filled in, so ``{}`` and
    ``{"obstacles": True}`` are one), on the same simulator (`versions`' physics and track
    format; default: this one's). The package's version is recorded beside it, not part of it:
    a release that changes no dynamics keeps every result comparable."""
    versions = versions or league_versions()
    options = {name: value if value is None else type(getattr(RaceOptions, name))(value)  # 1 and 1.0: one width
               for name, value in _full_options(env_options).items()}
    what = {"seed": int(seed), "episodes": int(episodes), "env_options": options,
            "physics": versions["physics"], "track_format": versions["track_format"]}
    return hashlib.sha256(json.dumps(what, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:16]


# --------------------------------------------------------------------------- metrics_run


@dataclass(frozen=True)
class EpisodeResult:
    seed: int
    steps: int
    episode_return: float
    mean_speed: float
    outcome: str  # finished, off_road, wrong_direction, too_slow, timeout or dnf
    reason: str | None = None  # why it stopped, for anything but "finished"

    def to_dict(self) -> dict:
        return {"seed": self.seed, "steps": self.steps, "return": self.episode_return,
                "mean_speed": self.mean_speed, "outcome": self.outcome, "reason": self.reason}

    @classmethod
    def from_dict(cls, data: dict) -> EpisodeResult:
        return cls(int(data["seed"]), int(data["steps"]), float(data["return"]), float(data["mean_speed"]),
                   data["outcome"], data.get("reason"))


@dataclass(frozen=True)
class MetricsResult:
    """The result of `metrics_run`: per-episode figures, totals, and what produced them (`settings`:
    the run's options, the versions of the simulator and package, and the `result_key`)."""

    episodes: list[EpisodeResult]
    settings: dict = field(default_factory=dict)

    @property
    def episodes_total(self) -> int:
        return len(self.episodes)

    @property
    def completed(self) -> int:
        return sum(e.outcome == "finished" for e in self.episodes)

    @property
    def mean_return(self) -> float:
        return _mean([e.episode_return for e in self.episodes])

    @property
    def mean_steps(self) -> float:
        return _mean([e.steps for e in self.episodes])

    @property
    def mean_speed(self) -> float:
        return _mean([e.mean_speed for e in self.episodes])

    def outcome_counts(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for episode in self.episodes:
            counts[episode.outcome] = counts.get(episode.outcome, 0) + 1
        return counts

    def to_dict(self) -> dict:
        return {
            "episodes": [e.to_dict() for e in self.episodes],
            "completed": self.completed,
            "episodes_total": self.episodes_total,
            "mean_return": self.mean_return,
            "mean_steps": self.mean_steps,
            "mean_speed": self.mean_speed,
            "settings": self.settings,
        }

    @classmethod
    def from_dict(cls, data: dict) -> MetricsResult:
        return cls([EpisodeResult.from_dict(e) for e in data["episodes"]], dict(data.get("settings", {})))

    def table(self, per_episode: bool = False) -> str:
        """A text summary (and, with ``per_episode``, one line per episode as the thesis printed)."""
        lines = []
        if per_episode:
            lines.append(f"{'episode':>7}  {'seed':>10}  {'steps':>5}  {'return':>7}  {'speed':>6}  outcome")
            for i, e in enumerate(self.episodes):
                outcome = e.outcome if e.reason is None or e.outcome != "dnf" else f"dnf: {e.reason}"
                lines.append(f"{i:>7}  {e.seed:>10}  {e.steps:>5}  {e.episode_return:>7.3f}  "
                             f"{e.mean_speed:>6.3f}  {outcome}")
            lines.append("")
        s = self.settings
        lines.append(f"{s.get('agent', 'agent')}: {self.episodes_total} episodes, seed {s.get('seed')}, "
                     f"{_options_text(s.get('env_options', {}))}")
        outcomes = ", ".join(f"{OUTCOME_TEXT.get(k, k)} {v}" for k, v in sorted(self.outcome_counts().items()))
        rows = [("completed", f"{self.completed} / {self.episodes_total}"), ("mean return", f"{self.mean_return:.3f}"),
                ("mean steps", f"{self.mean_steps:.1f}"), ("mean speed", f"{self.mean_speed:.3f}"),
                ("outcomes", outcomes)]
        if s.get("versions"):
            rows.append(("simulator", versions_text(s["versions"])))
        if s.get("result_key"):
            rows.append(("result key", f"{s['result_key']} (results with the same key compare)"))
        lines += [f"  {label:<12} {value}" for label, value in rows]
        return "\n".join(lines)


def _mean(values: Sequence[float]) -> float:
    return float(np.mean(values)) if len(values) else 0.0


def versions_text(versions: dict) -> str:
    return f"physics {versions['physics']}, track format {versions['track_format']} (league {versions['package']})"


def _options_text(options: dict) -> str:
    switches = ("obstacles", "chicanes", "turn_limit", "low_speed_termination")
    on = [name.replace("_", " ") for name in switches if options.get(name, True)]
    return "options: " + (", ".join(on) if on else "none")


def run_episode(env: Any, agent: Agent, seed: int) -> EpisodeResult:
    """One episode of `agent` in a MicroRacerEnv, seeded, one agent call per step (the way the
    thesis evaluated); an AgentError ends it as a DNF. `metrics_run` gives the same results for
    all its episodes at once."""
    try:
        _reset(agent)
    except AgentError as error:
        return EpisodeResult(seed, 0, 0.0, 0.0, "dnf", error.reason)
    obs, info = env.reset(seed=seed)
    steps, total_return, speed_sum = 0, 0.0, 0.0
    while True:
        try:
            action = agent(obs[None, :])[0]
        except AgentError as error:
            return EpisodeResult(seed, steps, total_return, speed_sum / max(steps, 1), "dnf", error.reason)
        obs, reward, terminated, truncated, info = env.step(action)
        steps += 1
        total_return += reward
        if terminated or truncated:
            break
        speed_sum += info["speed"]  # SPEC: speeds of the non-final steps, divided by all steps
    outcome = "timeout" if truncated and not terminated else info["outcome"]
    reason = None if outcome == "finished" else OUTCOME_TEXT[outcome]
    return EpisodeResult(seed, steps, total_return, speed_sum / steps, outcome, reason)


def _reset(agent: Agent) -> None:
    reset = getattr(agent, "reset", None)  # optional for duck-typed agents
    if reset is not None:
        reset()


def metrics_run(agent: Agent | str | os.PathLike, episodes: int = 100, seed: int = 0, progress: bool = False,
                on_episode: Callable[[int, EpisodeResult], None] | None = None, **env_options) -> MetricsResult:
    """Evaluate an agent over `episodes` random tracks (SPEC "Evaluation run").

    The episodes run in lockstep (up to `LOCKSTEP_EPISODES` at a time): each step, the agent is
    called once with the observations of every episode still running (a model fixed to batch
    size 1 is called row by row). Each
    episode's figures are those of running it alone (`run_episode`); only a model's batched
    float arithmetic may differ in the last bits from one observation at a time.

    Args:
        agent: an :class:`~league.agents.Agent` (or a path / "heuristic", loaded with
            ``load_agent``). Its ``obs_dim`` chooses the observation (5: compact, 20: lidar).
            ``agent.reset()`` is called once, before the run.
        episodes: number of episodes, each on a fresh track.
        seed: the run's seed; episode i uses ``episode_seeds(seed, episodes)[i]``
            (``SeedSequence(seed).generate_state``), so the same seed means the same tracks and
            initial speeds for every agent, and the same agent and seed the same metrics. The
            tracks come from this process's track cache (`league.track.episode_start`).
        progress: show a tqdm progress bar (on stderr), one tick per finished episode.
        on_episode: called as ``on_episode(i, episode_result)`` as each episode ends, in the
            order they end (e.g. a server worker's heartbeat or partial results).
        **env_options: options of ``league.MicroRacerEnv`` (obstacles, chicanes, turn_limit,
            low_speed_termination, curves, track_width, n_obstacles, tstep, max_episode_steps).

    A failing agent call (AgentError) fails the episodes it was asked for, as DNFs with the
    reason; when the model itself failed on the batch (``isolable``), the step is asked again
    row by row, so only the episodes whose observation makes it fail (or gives NaN actions) end.

    Returns:
        MetricsResult: per episode seed, steps, return, mean speed, outcome ("finished",
        "off_road", "wrong_direction", "too_slow", "timeout" when truncated, "dnf" when the
        agent failed, with its reason); totals completed / episodes_total, mean return,
        mean steps, mean speed; ``settings``, what produced them: seed, episodes, every
        environment option, ``versions`` (`league_versions`) and ``result_key`` (`result_key`:
        results with the same key compare); ``to_dict()`` and ``table()``.
    """
    agent = as_agent(agent)
    env_options = _checked_options(env_options)
    options = RaceOptions.from_kwargs(observation=observation_name(agent.obs_dim), **env_options)
    seeds = episode_seeds(seed, episodes)
    results: list[EpisodeResult | None] = [None] * episodes
    with tqdm(total=episodes, disable=not progress, desc=agent.name, unit="ep", dynamic_ncols=True) as bar:

        completed = 0

        def finish(i: int, result: EpisodeResult) -> None:
            nonlocal completed
            results[i] = result
            completed += result.outcome == "finished"
            if on_episode is not None:
                on_episode(i, result)
            if progress:
                bar.update(1)
                bar.set_postfix(completed=completed, refresh=False)

        try:
            _reset(agent)
        except AgentError as error:
            for i, episode_seed in enumerate(seeds):
                finish(i, EpisodeResult(episode_seed, 0, 0.0, 0.0, "dnf", error.reason))
        else:
            for first in range(0, episodes, LOCKSTEP_EPISODES):
                chunk = seeds[first:first + LOCKSTEP_EPISODES]
                _run_lockstep(agent, chunk, options, lambda i, result, first=first: finish(first + i, result))
    versions = league_versions()
    settings = {"agent": agent.name, "obs_dim": agent.obs_dim, "episodes": episodes, "seed": seed,
                "seeding": "numpy.random.SeedSequence(seed).generate_state(episodes)",
                "lockstep_episodes": LOCKSTEP_EPISODES,  # batched agent calls: tells these results from older ones
                "env_options": _full_options(env_options), "versions": versions,
                "result_key": result_key(seed, episodes, env_options, versions)}
    return MetricsResult(results, settings)


def _run_lockstep(agent: Agent, seeds: list[int], options: RaceOptions,
                  finish: Callable[[int, EpisodeResult], None]) -> None:
    """Every episode on its own car and track, advanced together until all have ended."""
    n = len(seeds)
    cars = new_cars(max(n, 1), options)
    for i, episode_seed in enumerate(seeds):
        place_car(cars, i, *episode_start(episode_seed, options))
    steps, returns, speed_sums = np.zeros(n, dtype=np.int64), np.zeros(n), np.zeros(n)
    actions = np.zeros((max(n, 1), 2), dtype=np.float32)

    def end(i: int, outcome: str, reason: str | None) -> None:
        cars.retire(i)  # a car out of time or whose agent failed stops where it is
        finish(i, EpisodeResult(seeds[i], int(steps[i]), float(returns[i]),
                                float(speed_sums[i] / max(steps[i], 1)), outcome, reason))

    # Each step's bookkeeping is a few whole-array operations (no per-episode Python but for the
    # episodes that end): the same additions, car by car, as masked assignments would make.
    outcome, reward, speed = cars.outcome, cars.reward, cars.speed  # (the batch's own arrays, updated in place)
    whole = len(outcome) == n
    while True:
        running = outcome == RUNNING if whole else outcome[:n] == RUNNING
        rows = running.nonzero()[0]
        if not len(rows):
            return
        answers, failures = _ask(agent, cars.obs[rows])
        if failures:
            for k, reason in failures.items():
                end(int(rows[k]), "dnf", reason)
            if len(failures) == len(rows):
                continue
        actions[rows] = answers
        moving = outcome == RUNNING if failures or not whole else running
        stopped, timed_out = cars.step_episodes(actions, options.max_episode_steps)
        np.add(steps, 1, out=steps, where=moving)
        np.add(returns, reward, out=returns, where=moving)
        ended = stopped | timed_out  # (cars that were moving)
        driving = moving ^ ended
        np.add(speed_sums, speed, out=speed_sums, where=driving)  # SPEC: speeds of the non-final steps, / all steps
        if ended.any():
            for i in ended.nonzero()[0]:
                outcome_i = "timeout" if timed_out[i] else OUTCOMES[outcome[i]]
                end(int(i), outcome_i, None if outcome[i] == FINISHED else OUTCOME_TEXT[outcome_i])


def _ask(agent: Agent, obs: np.ndarray) -> tuple[np.ndarray, dict[int, str]]:
    """The agent's actions for a batch of observations, and {row: reason} for the rows that failed.

    One call for the batch; when the model itself failed on it (an isolable AgentError), the rows
    are asked one by one, so that only those whose observation makes the model fail fail.
    """
    try:
        return agent(obs), {}
    except AgentError as error:
        if not error.isolable or len(obs) == 1:
            return np.zeros((len(obs), 2), dtype=np.float32), {k: error.reason for k in range(len(obs))}
    actions, failures = np.zeros((len(obs), 2), dtype=np.float32), {}
    for k in range(len(obs)):
        try:
            actions[k] = agent(obs[k:k + 1])[0]
        except AgentError as error:
            failures[k] = error.reason
    return actions, failures


# --------------------------------------------------------------------------- race


@dataclass
class CarLog:
    """One car's race: the states after each of its steps (index 0 = the start) and its actions."""

    name: str
    x: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    heading: list[float] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    acc: list[float] = field(default_factory=list)
    turn: list[float] = field(default_factory=list)
    outcome: str = "running"
    reason: str | None = None
    info: dict = field(default_factory=dict)

    def record_state(self, states: dict, i: int) -> None:
        self.x.append(float(states["x"][i]))
        self.y.append(float(states["y"][i]))
        self.heading.append(float(states["heading"][i]))
        self.speed.append(float(states["speed"][i]))

    def record_action(self, action: np.ndarray) -> None:
        self.acc.append(float(action[0]))
        self.turn.append(float(action[1]))

    def positions(self) -> np.ndarray:
        return np.column_stack([self.x, self.y])

    def to_replay(self) -> dict:
        return {key: np.round(getattr(self, key), decimals).tolist() for key, decimals in DECIMALS.items()}


@dataclass
class RaceResult:
    """The result of `race`: the classification, each car's full-precision log, and the replay."""

    classification: list[dict]
    cars: list[CarLog]
    replay: dict

    @property
    def names(self) -> list[str]:
        return [car.name for car in self.cars]

    def to_dict(self) -> dict:
        return {"seed": self.replay["seed"], "names": self.names, "classification": self.classification,
                "env_options": self.replay["env_options"]}

    def table(self) -> str:
        return classification_table(self.classification)


def classification_table(classification: list[dict]) -> str:
    lines = [f"{'pos':>3}  {'car':<6} {'name':<24} {'result':<16} {'time':>7}  {'distance':>8}"]
    for row in classification:
        result = "finished" if row["outcome"] == "finished" else OUTCOME_TEXT.get(row["outcome"], row["outcome"])
        lines.append(f"{row['position']:>3}  {row['car']:<6} {row['name'][:24]:<24} {result:<16} "
                     f"{row['time']:>6.2f}s  {row['distance']:>8.3f}")
        if row["outcome"] == "dnf" and row.get("reason"):
            lines.append(f"{'':>12}{row['reason']}")
    return "\n".join(lines)


def race(agents: Sequence[Agent | str | os.PathLike], seed: int = 0, names: Sequence[str] | None = None, *,
         track: Track | None = None, initial_speed: float | None = None, **env_options) -> RaceResult:
    """Race agents against each other on one shared track (SPEC "Race").

    Args:
        agents: one agent per car (Agents, or paths / "heuristic" loaded with ``load_agent``).
            Compact and lidar agents may race together: the environment then produces lidar
            observations and compact agents get their compact view of them.
        seed: seeds the track and the common initial speed; the same agents and seed give the
            same race, position for position.
        names: display names (default: the agents' names, made unique).
        track, initial_speed: race on a given Track / from a given speed instead of drawing them.
        **env_options: options of ``league.make_parallel_env`` (as ``league.MicroRacerEnv``).

    A car whose agent fails (AgentError) is out of the race at once as a DNF with the reason;
    the others go on. The race ends when every car is done.

    Returns:
        RaceResult with ``classification`` (finishers by interpolated finish time, then the
        others by distance covered; per car: car, name, position, outcome, time, distance,
        reason) and ``replay`` (see :func:`save_replay`).
    """
    agents = [as_agent(agent) for agent in agents]
    if not agents:
        raise ValueError("a race needs at least one agent")
    names = _unique_names(list(names) if names is not None else [a.name for a in agents])
    if len(names) != len(agents):
        raise ValueError(f"{len(names)} names for {len(agents)} agents")
    options = _checked_options(env_options)
    mode = "lidar" if any(a.obs_dim == LIDAR_DIM for a in agents) else "compact"
    penv = parallel_env(n_cars=len(agents), observation=mode, **options)
    reset_options = {key: value for key, value in (("track", track), ("initial_speed", initial_speed))
                     if value is not None}
    obs, infos = penv.reset(seed=seed, options=reset_options or None)
    cars = [CarLog(name) for name in names]
    for agent, car in zip(agents, cars):
        try:
            _reset(agent)
        except AgentError as error:
            car.outcome, car.reason = "dnf", error.reason
    _drive(penv, agents, cars, obs, infos)
    classification = _classify(cars, penv.options.tstep)
    replay = _build_replay(penv, cars, classification, seed, options, mode, track_given=track is not None)
    penv.close()
    return RaceResult(classification, cars, replay)


def _drive(penv: Any, agents: list[Agent], cars: list[CarLog], obs: dict, infos: dict) -> None:
    """Step the race until every car is done; a car whose agent fails is retired (DNF).

    Each step asks every racing car's agent first and only then waits for the answers (agents in
    sandboxes think in parallel), then moves the cars with the simulator's arrays
    (`step_arrays`): the states and actions are kept as one array per step and made into each
    car's log at the end, so no Python runs per car beyond its agent's call, but when a car ends
    (its info then, as the PettingZoo step gives it)."""
    batch, names = penv.cars, penv.possible_agents
    for i, car in enumerate(cars):
        car.info = infos[names[i]]
        if car.outcome == "dnf":
            penv.retire(names[i])
    n = len(cars)
    taken = np.zeros(n, dtype=np.int64)  # steps of each car: a car steps from the start until it is done
    states = [(batch.x.copy(), batch.y.copy(), batch.heading.copy(), batch.speed.copy())]
    actions = []
    while penv.agents:
        seen = batch.obs.copy()  # this step's observations, the agents' own (no agent sees the simulator's)
        live = [int(car_id[4:]) for car_id in penv.agents]
        pending = [_request(agents[i], seen[i]) for i in live]
        step = np.zeros((n, 2), dtype=np.float32)
        stepped = []
        for i, answer in zip(live, pending):
            try:
                step[i] = answer()[0]
            except AgentError as error:
                cars[i].info = penv.info(names[i])  # its last step's (it has not moved since)
                cars[i].outcome, cars[i].reason = "dnf", error.reason
                penv.retire(names[i])
            else:
                stepped.append(i)
        if not stepped:
            break
        _, _, terminated, truncated = penv.step_arrays(step)
        taken[stepped] += 1
        states.append((batch.x.copy(), batch.y.copy(), batch.heading.copy(), batch.speed.copy()))
        actions.append(step)
        for i in (terminated | truncated).nonzero()[0]:  # (step_arrays took them out of penv.agents)
            cars[i].info = info = penv.info(names[i])
            cars[i].outcome = info["outcome"] if terminated[i] else "timeout"
    _record(cars, taken, states, actions)


def _record(cars: list[CarLog], taken: np.ndarray, states: list[tuple], actions: list[np.ndarray]) -> None:
    """Each car's log from the race's arrays: its states from the start and its actions, step by step."""
    x, y, heading, speed = (np.stack(column) for column in zip(*states))
    moves = np.stack(actions) if actions else np.zeros((0, len(cars), 2), dtype=np.float32)
    for i, car in enumerate(cars):
        k = int(taken[i])
        car.x, car.y = x[:k + 1, i].tolist(), y[:k + 1, i].tolist()
        car.heading, car.speed = heading[:k + 1, i].tolist(), speed[:k + 1, i].tolist()
        car.acc, car.turn = moves[:k, i, 0].tolist(), moves[:k, i, 1].tolist()


def _request(agent: Agent, observation: np.ndarray) -> Callable[[], np.ndarray]:
    """The agent's pending answer for one car (a compact agent gets its view of a lidar observation)."""
    obs = observation[None, :]
    if agent.obs_dim == COMPACT_DIM and obs.shape[1] == LIDAR_DIM:
        obs = compact_from_lidar(obs)
    request = getattr(agent, "request", None)  # duck-typed agents may have only __call__
    return request(obs) if request is not None else functools.partial(agent, obs)


def _classify(cars: list[CarLog], tstep: float) -> list[dict]:
    rows = []
    for i, car in enumerate(cars):
        finished = car.outcome == "finished"
        time = car.info.get("finish_time") if finished else (len(car.x) - 1) * tstep
        reason = car.reason if car.outcome == "dnf" else (None if finished else OUTCOME_TEXT.get(car.outcome))
        rows.append({"car": f"car_{i}", "name": car.name, "position": 0, "outcome": car.outcome,
                     "time": float(time), "distance": float(car.info.get("distance", 0.0)), "reason": reason})
    finishers = sorted((r for r in rows if r["outcome"] == "finished"), key=lambda r: r["time"])
    others = sorted((r for r in rows if r["outcome"] != "finished"), key=lambda r: -r["distance"])
    ordered = finishers + others
    for position, row in enumerate(ordered, start=1):
        row["position"] = position
    return ordered


def _unique_names(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    unique = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        unique.append(name if names.count(name) == 1 else f"{name} #{seen[name]}")
    return unique


# --------------------------------------------------------------------------- replays


def _build_replay(penv: Any, cars: list[CarLog], classification: list[dict], seed: int, options: dict,
                  mode: str, track_given: bool) -> dict:
    return {
        "format": REPLAY_FORMAT,
        "version": REPLAY_VERSION,
        "seed": seed,
        "names": [car.name for car in cars],
        "env_options": _full_options(options),
        "observation": mode,
        "tstep": penv.options.tstep,
        "track": penv.track.to_dict(),
        "track_given": track_given,  # raced on a given track rather than the seed's
        "versions": league_versions(),  # the simulator and package that raced it
        "initial_speed": cars[0].speed[0],
        "classification": classification,
        "cars": [car.to_replay() for car in cars],
    }


def save_replay(replay: dict | RaceResult, path: str | os.PathLike) -> Path:
    """Write a replay as compact JSON. Per car, lists x, y, heading, speed (the start, then after each
    step) and acc, turn (each step's action), rounded to ``DECIMALS``; the track in ``Track.to_dict`` form."""
    if isinstance(replay, RaceResult):
        replay = replay.replay
    path = Path(path)
    path.write_text(json.dumps(replay, separators=(",", ":")))
    return path


def load_replay(path: str | os.PathLike) -> dict:
    """Read a replay written by `save_replay`; raise ValueError when it is not one of a known version."""
    try:
        replay = json.loads(Path(path).read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"{path} is not a replay file (not JSON: {error})") from error
    if not isinstance(replay, dict) or replay.get("format") != REPLAY_FORMAT:
        raise ValueError(f"{path} is not a MicroRacer replay (no \"format\": \"{REPLAY_FORMAT}\")")
    if replay.get("version") != REPLAY_VERSION:
        raise ValueError(f"{path} is a replay of version {replay.get('version')}; "
                         f"this league reads version {REPLAY_VERSION}")
    return replay


def replay_track(replay: dict) -> Track:
    """The replay's Track, rebuilt from its compact form."""
    return Track.from_dict(replay["track"])


def race_again(replay: dict, agents: Sequence[Agent | str | os.PathLike]) -> RaceResult:
    """Re-run a replay's race from its seed and options with the given agents (one per car)."""
    given = ({"track": replay_track(replay), "initial_speed": replay["initial_speed"]}
             if replay.get("track_given") else {})
    return race(agents, seed=replay["seed"], names=replay["names"], **given, **replay["env_options"])


__all__ = [
    "CarLog", "EpisodeResult", "MetricsResult", "RaceResult", "episode_seeds", "load_replay", "metrics_run",
    "race", "race_again", "replay_track", "run_episode", "save_replay", "classification_table",
]
