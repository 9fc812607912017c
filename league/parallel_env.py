"""MicroRacer for N cars on one shared track, as a PettingZoo ParallelEnv."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.utils import parallel_to_aec, wrappers

from league.cars import as_actions, start_cars
from league.constants import FINISHED, MAP_EXTENT, MAX_SPEED, RUNNING
from league.env import action_space, env_info, observation_space
from league.options import RaceOptions
from league.render import FRAME_SHAPE, EnvRendering
from league.track import Track


class MicroRacerParallelEnv(EnvRendering, ParallelEnv):
    """
    ## Description
    N non-interacting cars (`car_0` ... `car_{N-1}`) race one lap of the same random track,
    from the same start with the same initial speed; cars may overlap. Each car has the
    observation, action, reward and termination rules of `league/MicroRacer-v0`.

    ## Agents
    A car that is done (finished, crashed, or out of time) leaves `agents`; the episode ends
    when every car is done. Actions sent for a car that is done are ignored (as PettingZoo's
    `aec_to_parallel` does); an agent name that is not one of `possible_agents` raises.

    ## Spaces and state
    `observation_spaces` / `action_spaces` (dicts, the same objects as `observation_space(agent)`
    / `action_space(agent)`). `state()` is every car's `[x, y, heading, speed]` (done cars where
    they stopped, heading in [-pi, pi)), flattened to a float32 array of `state_space`,
    shape `(4 * n_cars,)`: the global view for centralised critics.

    ## Infos
    Per car, the same keys and types at every step from `reset`: "outcome" (its name, as in
    `league/MicroRacer-v0`) and "outcome_code" (its index in `league.constants.OUTCOMES`),
    "progress", "time", "distance", "speed", "position" (1-based finishing order) and
    "finish_time" (s), both 0 until the car finishes; the finish time is interpolated inside the
    step in which the car crossed the line, so cars finishing in the same step are ordered.
    Numbers are numpy scalars. `numeric_infos=True` leaves out the "outcome" string, for
    libraries that turn every info value into a tensor (torchrl's `PettingZooWrapper`).

    ## Batched interface
    `step_arrays(actions)` takes a float32 `(n_cars, 2)` array and returns arrays
    `(obs, rewards, terminated, truncated)`, skipping the per-agent dicts (for training); like
    `step`, it takes the cars done in the step out of `agents`. `info(agent)` is a car's info, as
    `step` gives it.

    ## Arguments
    ```python
    league.make_parallel_env(n_cars=4, render_mode=None, numeric_infos=False, **options)
    league.make_aec_env(n_cars=4, render_mode=None, **options)  # the AEC form
    ```
    `**options` are those of league/MicroRacer-v0. As PettingZoo's environment modules do, the
    module `league.parallel_env` names these two `parallel_env()` and `env()`.
    `max_cycles=N` (PettingZoo's name, as its `max_cycles_test` passes it) is `max_episode_steps=N`:
    a car still running after N steps is truncated.
    Rendering and frames as `league/MicroRacer-v0` (`metadata["render_frame_shape"]`).
    """

    metadata = {"name": "microracer_v0", "render_modes": ["human", "rgb_array"], "render_fps": 25,
                "is_parallelizable": True, "render_frame_shape": FRAME_SHAPE}
    maker = "league.make_parallel_env"

    def __init__(self, n_cars: int = 4, render_mode: str | None = None, numeric_infos: bool = False,
                 max_cycles: int | None = None, **options):
        if not isinstance(n_cars, (int, np.integer)) or n_cars < 1:
            raise ValueError(f"n_cars must be an integer >= 1, got {n_cars!r}")
        if max_cycles is not None:
            if "max_episode_steps" in options:
                raise TypeError("give max_cycles (PettingZoo's name) or max_episode_steps, not both: they are "
                                "the same episode limit")
            options["max_episode_steps"] = max_cycles
        self.options = RaceOptions.from_kwargs("parallel_env", **options)
        self.render_mode = self.check_render_mode(render_mode)
        self.numeric_infos = numeric_infos
        self.possible_agents = [f"car_{i}" for i in range(n_cars)]
        self.agents: list[str] = []
        self.observation_spaces = {a: observation_space(self.options.observation) for a in self.possible_agents}
        self.action_spaces = {a: action_space() for a in self.possible_agents}
        self.state_space = state_space(n_cars)
        self.n_cars = n_cars
        self.cars = None  # league.lidar.CarBatch, made at reset
        self.track: Track | None = None
        self.np_random, _ = gym.utils.seeding.np_random(None)
        self._trails: list[list[tuple[float, float]]] = []
        self._finishers = 0

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def state(self) -> np.ndarray:
        if self.cars is None:
            raise RuntimeError("call reset() before state()")
        c = self.cars
        heading = np.mod(c.heading + np.pi, 2 * np.pi) - np.pi
        return np.column_stack([c.x, c.y, heading, c.speed]).astype(np.float32).ravel()

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self.np_random, _ = gym.utils.seeding.np_random(seed)
        self.track, speed = self.options.episode_start(self.np_random, options)
        self.cars = start_cars(self.cars, self.n_cars, self.track, self.options, speed)
        obs = self.cars.obs
        self.agents = self.possible_agents[:]
        self.position = np.zeros(self.n_cars, dtype=np.int64)
        self._finishers = 0
        self._trails = [[self.track.start_position] for _ in self.agents]
        infos = self._infos({agent: i for i, agent in enumerate(self.agents)})
        return {agent: obs[i].copy() for i, agent in enumerate(self.agents)}, infos

    def step_arrays(self, actions: np.ndarray):
        """Advance all running cars: actions float32 (n_cars, 2) -> obs, rewards, terminated, truncated.

        The arrays are the simulator's own buffers, overwritten by the next step: copy what you keep.
        The cars done in this step leave `agents`.
        """
        if self.cars is None:
            raise RuntimeError("call reset() before step()")
        cars = self.cars
        was_running = cars.outcome == RUNNING
        cars.step(as_actions(actions, self.n_cars))
        terminated = was_running & (cars.outcome != RUNNING)
        finished_now = terminated & (cars.outcome == FINISHED)
        if finished_now.any():
            self._place_finishers(finished_now)
        truncated = was_running & ~terminated & (cars.steps >= self.options.max_episode_steps)
        done = terminated | truncated
        if done.any():
            self.agents = [agent for agent in self.agents if not done[int(agent[4:])]]
        if self.render_mode is not None:
            for i in np.flatnonzero(was_running):
                self._trails[i].append((float(cars.x[i]), float(cars.y[i])))
        return cars.obs, cars.reward, terminated, truncated

    def step(self, actions: dict):
        unknown = set(actions) - set(self.possible_agents)
        if unknown:
            raise ValueError(f"actions for unknown agents {sorted(unknown)}; the agents are {self.possible_agents}")
        missing = [agent for agent in self.agents if agent not in actions]
        if missing:
            raise ValueError(f"missing actions for {missing}; every live agent needs an action")
        batch = np.zeros((self.n_cars, 2), dtype=np.float32)
        index = {agent: int(agent[4:]) for agent in self.agents}
        for agent, i in index.items():
            batch[i] = as_actions(actions[agent], 1)[0]
        obs, rewards, terminated, truncated = self.step_arrays(batch)
        observations = {a: obs[i].copy() for a, i in index.items()}
        reward_dict = {a: float(rewards[i]) for a, i in index.items()}
        terminations = {a: bool(terminated[i]) for a, i in index.items()}
        truncations = {a: bool(truncated[i]) for a, i in index.items()}
        infos = self._infos(index)
        if self.render_mode == "human":
            self.render()
        return observations, reward_dict, terminations, truncations, infos

    def retire(self, agent: str) -> None:
        """Take a car out of the race (say, its agent failed): it leaves `agents` with outcome "retired"."""
        if agent not in self.agents:
            raise ValueError(f"{agent!r} is not racing; live agents: {self.agents}")
        self.cars.retire(int(agent[4:]))
        self.agents.remove(agent)

    def info(self, agent: str) -> dict:
        """The car's info, as `step` gives it (its last step's once it is done)."""
        if agent not in self.possible_agents:
            raise ValueError(f"unknown agent {agent!r}; the agents are {self.possible_agents}")
        return self._infos({agent: int(agent[4:])})[agent]

    def _place_finishers(self, finished_now: np.ndarray):
        """Finishing positions by interpolated finish time (ties: lower car index first)."""
        if not finished_now.any():
            return
        cars = np.flatnonzero(finished_now)
        for i in cars[np.argsort(self.cars.finish_time[cars], kind="stable")]:
            self._finishers += 1
            self.position[i] = self._finishers

    def _infos(self, index: dict[str, int]) -> dict[str, dict]:
        """Infos of the cars in `index` (agent -> car), with the same keys at every step."""
        # 0 until a car finishes (not NaN: NaN != NaN breaks equality checks such as PettingZoo's seed test)
        finish_times = np.where(self.position > 0, self.cars.finish_time, 0.0)
        infos = {}
        for agent, i in index.items():
            info = infos[agent] = env_info(self.cars, i, self.numeric_infos)
            info["position"], info["finish_time"] = self.position[i], finish_times[i]  # numpy scalars
        return infos

    def car_states(self) -> dict[str, np.ndarray]:
        """Position, heading and speed of every car (done or not), as float64 arrays."""
        c = self.cars
        return {"x": c.x.copy(), "y": c.y.copy(), "heading": c.heading.copy(), "speed": c.speed.copy()}

    def scene(self):
        cars = self.cars
        if cars is None:
            return None
        return self.track, cars.x, cars.y, cars.heading, [np.array(t) for t in self._trails]


def state_space(n_cars: int) -> spaces.Box:
    """Bounds of `state()`: per car x and y in the map, heading in [-pi, pi], speed."""
    high = np.tile(np.array([MAP_EXTENT, MAP_EXTENT, np.pi, MAX_SPEED], dtype=np.float32), n_cars)
    low = np.tile(np.array([-MAP_EXTENT, -MAP_EXTENT, -np.pi, 0], dtype=np.float32), n_cars)
    return spaces.Box(low, high, dtype=np.float32)


def parallel_env(n_cars: int = 4, render_mode: str | None = None, numeric_infos: bool = False,
                 **options) -> MicroRacerParallelEnv:
    """N cars on one shared track (PettingZoo Parallel API); `league.make_parallel_env`."""
    return MicroRacerParallelEnv(n_cars=n_cars, render_mode=render_mode, numeric_infos=numeric_infos, **options)


def env(n_cars: int = 4, render_mode: str | None = None, **options):
    """The AEC form of `parallel_env`, through PettingZoo's conversion; `league.make_aec_env`."""
    aec = parallel_to_aec(parallel_env(n_cars=n_cars, render_mode=render_mode, **options))
    return wrappers.OrderEnforcingWrapper(aec) if not isinstance(aec, wrappers.OrderEnforcingWrapper) else aec
