"""MicroRacer as a native Gymnasium vector environment: N independent episodes, one compiled step."""
from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.utils import seeding

try:
    from gymnasium.vector import AutoresetMode, VectorEnv
except ImportError as error:  # Gymnasium 0.29: the single and the PettingZoo envs run on it, this one does not
    raise ImportError("league.vector_env needs Gymnasium >= 1.0 (its vector API): pip install -U gymnasium") from error
from gymnasium.vector.utils import batch_space

from league.cars import as_actions, new_cars, place_car
from league.constants import RUNNING
from league.env import action_space, observation_space
from league.options import RaceOptions
from league.render import EnvRendering
from league.track import Track, episode_start

INFO_KEYS = ("outcome", "outcome_code", "progress", "time", "distance", "speed")


class MicroRacerVectorEnv(EnvRendering, VectorEnv):
    """
    ## Description
    `num_envs` independent MicroRacer episodes (`league/MicroRacer-v0`), each with its own car
    on its own random track, advanced together by one call of the compiled core: sub-env i is
    exactly `MicroRacerEnv(**options)`, without a Python loop over cars or rays. Episodes end
    at different times; each car's time limit counts its own steps.

    ## Spaces
    `single_observation_space` and `single_action_space` are those of `league/MicroRacer-v0`;
    observations are a float32 `(num_envs, 5)` array (compact) or `(num_envs, 20)` (lidar),
    actions a `(num_envs, 2)` array of `[acceleration, turn]`.

    ## Autoreset
    `metadata["autoreset_mode"]`, as Gymnasium 1.x defines it. `AutoresetMode.NEXT_STEP` (the
    default): the step after a sub-env terminates or truncates resets it (its action is
    ignored, its reward is 0). `AutoresetMode.SAME_STEP`: the done sub-env is reset in the same
    step; its last observation and info are in `infos["final_obs"]` and `infos["final_info"]`
    (masks `infos["_final_obs"]`, `infos["_final_info"]`). `AutoresetMode.DISABLED`: reset done
    sub-envs yourself with `reset(options={"reset_mask": mask})`.

    ## Infos
    Arrays of shape `(num_envs,)`: "outcome" (names: "running", "finished", "off_road",
    "wrong_direction", "too_slow"), "outcome_code" (their index in `league.constants.OUTCOMES`),
    "progress" (lap fraction), "time" (s), "distance" and "speed", each with its all-True
    Gymnasium mask ("_outcome", ...). `numeric_infos=True` leaves out "outcome" (and its mask),
    for libraries that make a tensor of every info value (torchrl's `GymWrapper`).

    ## Tracks and seeding
    By default every episode draws a new random track (as the thesis does). `reset(seed=s)`
    seeds sub-env i as `MicroRacerEnv().reset(seed=s + i)`: the same track, initial speed and
    next tracks, so N single envs driven with the same actions give identical trajectories.
    `track_pool=K` draws each episode's track from a fixed pool of K tracks instead (a reset
    costs nothing then): track k of the pool is the track of `MicroRacerEnv().reset(seed=p + k)`,
    where p is the seed of the first seeded reset (or drawn from the env's seed); each episode
    picks one with its sub-env's generator and draws its initial speed as usual. Pool tracks
    come from the process's track cache (`league.track.episode_start`).

    ## Reset options
    `reset(options=...)` takes the single env's options ("track", "initial_speed") for every
    sub-env it resets, and "reset_mask" (a bool array: reset only those sub-envs).

    ## Stepping some sub-envs
    `step(actions, moving=mask)` (an addition to Gymnasium's interface) steps only the sub-envs
    in the bool array `mask`: the others stay exactly as they are (no move, no autoreset, reward
    0, not done). The baselines use it for the thesis' extra neutral step of some cars.

    ## Rendering
    `render_mode="rgb_array"`: `render()` draws sub-env 0 (its track, car and trail).

    ## Arguments
    ```python
    gymnasium.make_vec("league/MicroRacer-v0", num_envs=8, vectorization_mode="vector_entry_point",
                       **options)  # every option of league/MicroRacer-v0
    league.make_vector_env(num_envs=8, autoreset_mode=AutoresetMode.NEXT_STEP, track_pool=None,
                           render_mode=None, numeric_infos=False, **options)
    ```
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 25, "autoreset_mode": AutoresetMode.NEXT_STEP}
    maker = "league.make_vector_env"

    def __init__(self, num_envs: int = 8, render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, track_pool: int | None = None,
                 numeric_infos: bool = False, **options):
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if track_pool is not None and (not isinstance(track_pool, (int, np.integer)) or track_pool < 1):
            raise ValueError(f"track_pool must be a number of tracks >= 1, or None for a new track every episode; "
                             f"got {track_pool!r}")
        self.options = RaceOptions.from_kwargs(**options)
        self.num_envs = int(num_envs)
        self.render_mode = self.check_render_mode(render_mode)
        self.metadata = {**self.metadata, "autoreset_mode": AutoresetMode(autoreset_mode)}
        self.single_observation_space = observation_space(self.options.observation)
        self.single_action_space = action_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.track_pool = track_pool
        self.numeric_infos = numeric_infos
        self.info_keys = INFO_KEYS[1:] if numeric_infos else INFO_KEYS  # INFO_KEYS[0] is "outcome"
        self.cars = new_cars(self.num_envs, self.options)
        self.tracks: list[Track | None] = [None] * self.num_envs
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._pool: list[Track] = []
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)  # done in the previous step
        self._mask = np.ones(self.num_envs, dtype=bool)
        self._mask.flags.writeable = False
        self._info_masks = {f"_{key}": self._mask for key in self.info_keys}
        self._trail: list[tuple[float, float]] = []

    @property
    def autoreset_mode(self) -> AutoresetMode:
        return self.metadata["autoreset_mode"]

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        options = dict(options or {})
        mask = _reset_mask(options.pop("reset_mask", None), self.num_envs)
        seeds, seeded = _sub_env_seeds(seed, self.num_envs), isinstance(seed, (int, np.integer))
        if seeded:
            self._np_random, self._np_random_seed = seeding.np_random(int(seed))
        for i in np.flatnonzero(mask):
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(seeds[i])[0]
        if self.track_pool and (seeded or not self._pool):
            self._fill_pool(int(seed) if seeded else int(self.np_random.integers(2**31)))
        for i in np.flatnonzero(mask):
            self._start_episode(i, options)
        self._needs_reset[mask] = False
        return self._observe()

    def step(self, actions, moving=None):
        if moving is None and self.render_mode is None:
            return self._step_all(actions)
        cars, mode = self.cars, self.autoreset_mode
        moving = self._mask if moving is None else np.asarray(moving, dtype=bool)  # (all: the read-only mask)
        if mode == AutoresetMode.DISABLED and (self._needs_reset & moving).any():
            raise self._pending_error()
        moving_first = cars.outcome[0] == RUNNING and moving[0]
        terminated, truncated = cars.step_episodes(as_actions(actions, self.num_envs), self.options.max_episode_steps,
                                                   moving)
        rewards = cars.reward.copy()
        if self.render_mode is not None and moving_first:
            self._trail.append((float(cars.x[0]), float(cars.y[0])))
        obs, infos = self._end_episodes(terminated, truncated, moving)
        return obs, rewards, terminated, truncated, infos

    def _step_all(self, actions):
        """`step` of every sub-env, not rendered: one call of the compiled core, and the Python
        bookkeeping of `_end_episodes` only in the steps where an episode ends or starts again
        (without either, it would leave everything as it is)."""
        cars, mode = self.cars, self.autoreset_mode
        stepped = cars.step_vector(as_actions(actions, self.num_envs), self.options.max_episode_steps,
                                   self._needs_reset, mode == AutoresetMode.DISABLED, not self.numeric_infos,
                                   self._info_masks)
        if stepped is None:
            raise self._pending_error()
        obs, rewards, terminated, truncated, infos, n_done, n_pending = stepped
        if n_done or n_pending:
            obs, infos = self._end_episodes(terminated, truncated, self._mask)
        return obs, rewards, terminated, truncated, infos

    def _end_episodes(self, terminated: np.ndarray, truncated: np.ndarray, moving: np.ndarray):
        """After the cars' step: retire the cars out of time, restart the episodes the autoreset
        mode restarts now; the observations and infos."""
        cars, mode = self.cars, self.autoreset_mode
        done = terminated | truncated
        restart, final = self._needs_reset & moving, None  # next step: those done in the previous step
        if mode == AutoresetMode.SAME_STEP:
            restart = done
            if done.any():
                final = self._observe(truncated)
        if truncated.any():
            for i in np.flatnonzero(truncated):
                cars.retire(i)  # out of time: it stops where it is until its reset
        if restart.any():
            for i in np.flatnonzero(restart):
                self._start_episode(i)
        if mode == AutoresetMode.SAME_STEP:
            self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        else:
            self._needs_reset = done if moving is self._mask else np.where(moving, done, self._needs_reset)
        obs, infos = self._observe(truncated & ~restart)
        if final is not None:
            _add_final(infos, *final, done, self.info_keys)
        return obs, infos

    def _pending_error(self) -> RuntimeError:
        return RuntimeError(f"sub-envs {np.flatnonzero(self._needs_reset).tolist()} are done: reset them with "
                            "reset(options={'reset_mask': mask}) before stepping (autoreset_mode DISABLED)")

    def _start_episode(self, i: int, options: dict | None = None) -> None:
        """Sub-env i's next episode: as `MicroRacerEnv.reset`, from the sub-env's own generator."""
        options, rng = dict(options or {}), self._rngs[i]
        if options.get("track") is None and self.track_pool:
            options["track"] = self._pool[int(rng.integers(len(self._pool)))]
        track, speed = self.options.episode_start(rng, options)
        self.tracks[i] = track
        place_car(self.cars, i, track, speed)
        if i == 0:
            self._trail = [track.start_position]

    def _fill_pool(self, pool_seed: int) -> None:
        self._pool = [episode_start(pool_seed + k, self.options)[0] for k in range(self.track_pool)]

    def _observe(self, truncated: np.ndarray | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Copies of the observations and the infos of every sub-env; cars just out of time
        (`truncated`) are still "running"."""
        return self.cars.observe(truncated, not self.numeric_infos, self._info_masks)

    def scene(self):
        """Sub-env 0: its track, car and trail."""
        if self.tracks[0] is None:
            return None
        cars = self.cars
        return self.tracks[0], cars.x[:1], cars.y[:1], cars.heading[:1], [np.array(self._trail)]


def _add_final(infos: dict, final_obs: np.ndarray, final_infos: dict, done: np.ndarray, keys: tuple) -> None:
    """Same-step autoreset: the done sub-envs' last observations and infos, as SyncVectorEnv gives them."""
    infos["final_obs"] = np.full(len(done), None, dtype=object)
    for i in np.flatnonzero(done):
        infos["final_obs"][i] = final_obs[i]
    infos["final_info"] = {key: final_infos[key] for key in keys} | {f"_{key}": done for key in keys}
    infos["_final_obs"] = infos["_final_info"] = done


def _sub_env_seeds(seed: int | list[int | None] | None, num_envs: int) -> list[int | None]:
    """As SyncVectorEnv: an int seeds sub-env i with seed + i; a list gives each its own."""
    if seed is None:
        return [None] * num_envs
    if isinstance(seed, (int, np.integer)):
        return [int(seed) + i for i in range(num_envs)]
    seeds = list(seed)
    if len(seeds) != num_envs:
        raise ValueError(f"a list of seeds needs one per sub-env: {num_envs}, got {len(seeds)}")
    return seeds


def _reset_mask(mask: Any, num_envs: int) -> np.ndarray:
    if mask is None:
        return np.ones(num_envs, dtype=bool)
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (num_envs,):
        raise ValueError(f"options['reset_mask'] must be a bool numpy array of shape ({num_envs},), got {mask!r}")
    return mask


def make_vector_env(num_envs: int = 8, render_mode: str | None = None, **options) -> MicroRacerVectorEnv:
    """`num_envs` independent MicroRacer episodes as a Gymnasium VectorEnv (see MicroRacerVectorEnv);
    `league.make_vector_env`."""
    return MicroRacerVectorEnv(num_envs=num_envs, render_mode=render_mode, **options)
