"""MicroRacer as a single-car Gymnasium environment."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from league.cars import as_actions, start_cars
from league.constants import MAX_LIDAR_RANGE, MAX_SPEED, MAX_TURN, N_RAYS, RUNNING
from league.options import RaceOptions
from league.render import FRAME_SHAPE, EnvRendering
from league.track import Track


def observation_space(observation: str) -> spaces.Box:
    if observation == "compact":
        low = np.array([-MAX_TURN, 0, 0, 0, 0], dtype=np.float32)
        high = np.array([MAX_TURN, MAX_LIDAR_RANGE, MAX_LIDAR_RANGE, MAX_LIDAR_RANGE, MAX_SPEED], dtype=np.float32)
    else:
        low = np.zeros(N_RAYS + 1, dtype=np.float32)
        high = np.array([MAX_LIDAR_RANGE] * N_RAYS + [MAX_SPEED], dtype=np.float32)
    return spaces.Box(low, high, dtype=np.float32)


def env_info(cars, i: int, numeric: bool = False) -> dict:
    """Car i's info: the same keys and types every step, numpy numbers beside the outcome's name
    (left out when `numeric`, for libraries that make a tensor of every info value)."""
    info = cars.info(i)
    if numeric:
        del info["outcome"]
    return info


def action_space() -> spaces.Box:
    """[acceleration, turn] in [-1, 1]; a new object each call, so each can be seeded on its own."""
    return spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)


class MicroRacerEnv(EnvRendering, gym.Env):
    """
    ## Description
    MicroRacer (Galletti, thesis, ch. 3): a car races one clockwise lap of a random closed
    track drawn from cubic splines and rasterised to a 1300 x 1300 grid, with a chicane and
    six obstacles. The car sees the track through a 19-ray lidar. Every reset draws a new track.

    ## Action Space
    `Box(-1, 1, (2,), float32)`: `[acceleration, turn]`; positive turn steers right. Values
    outside [-1, 1] are clipped; NaN or a wrong shape raises `ValueError`.

    ## Observation Space
    `observation="compact"` (default), `Box` of 5 numbers `[direction, left, max, right, speed]`:
    the angle (rad, positive = left) of the longest lidar ray, the readings of the rays beside
    it and of itself, and the speed. `observation="lidar"`: the 19 readings plus the speed.

    ## Rewards
    The distance covered in the step (`speed * tstep`); -3 for a crash.

    ## Starting State
    On the mid-line at polar angle 0, heading clockwise, speed ~ U(0, 0.5) (at least 0.07 with
    low-speed termination).

    ## Episode Termination
    `terminated` when the lap is complete or the car goes off road (border or obstacle), turns
    back (wrong direction) or, with low-speed termination, drops below speed 0.05. A crash
    leaves the car where it was and returns its last valid observation. `truncated` after
    `max_episode_steps` (4000 steps, 160 s): `gym.make` adds Gymnasium's `TimeLimit` wrapper
    (`gym.make(..., max_episode_steps=N)` changes it); a directly built `MicroRacerEnv` keeps
    time itself.

    ## Info
    The same keys and types at every step: "outcome" says why the episode ended ("running",
    "finished", "off_road", "wrong_direction", "too_slow") and "outcome_code" is its index in
    `league.constants.OUTCOMES` (0 to 4, the thesis' `completation` codes, a `numpy.int64`);
    "progress" (lap fraction), "time" (s), "distance" and "speed" (`numpy.float64`).
    `numeric_infos=True` leaves out the "outcome" string, for libraries that make a tensor of
    every info value (torchrl's `GymEnv`, whose `num_envs=N` runs N of these envs).

    ## Rendering
    `render_mode="rgb_array"` returns uint8 frames of one fixed shape, `metadata["render_frame_shape"]`
    (650, 650, 3): the whole world at 1 px = 2 map cells, so video recorders and pixel wrappers
    work across episodes. `render_mode="human"` shows them in a matplotlib window.

    ## Arguments
    ```python
    gymnasium.make("league/MicroRacer-v0", obstacles=True, chicanes=True, turn_limit=True,
                   low_speed_termination=True, observation="compact", curves=20,
                   track_width=0.04, n_obstacles=6, tstep=0.04, max_episode_steps=4000,
                   numeric_infos=False)
    ```
    An unknown argument raises Python's own `TypeError` ("got an unexpected keyword argument").
    `reset(options={"track": track})` races on a given `league.track.Track` instead of a new
    one; `options={"initial_speed": v}` sets the start speed. Many episodes at once, in one
    compiled step: `gymnasium.make_vec("league/MicroRacer-v0", num_envs=N,
    vectorization_mode="vector_entry_point")` or `league.make_vector_env(num_envs=N, track_pool=None,
    **options)` (`league.vector_env.MicroRacerVectorEnv`).

    ## Version History
    * v0: first version, SPEC of the reference implementation with a 1/500-accurate lidar.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 25, "render_frame_shape": FRAME_SHAPE}

    def __init__(self, render_mode: str | None = None, numeric_infos: bool = False, **options):
        self.options = RaceOptions.from_kwargs("MicroRacerEnv.__init__", **options)
        self.render_mode = self.check_render_mode(render_mode)
        self.numeric_infos = numeric_infos
        self.action_space = action_space()
        self.observation_space = observation_space(self.options.observation)
        self.cars = None  # league.lidar.CarBatch of one car, made at reset
        self.track: Track | None = None
        self._trail: list[tuple[float, float]] = []

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.track, speed = self.options.episode_start(self.np_random, options)
        self.cars = start_cars(self.cars, 1, self.track, self.options, speed)
        self._trail = [self.track.start_position]
        return self.cars.observation(0), env_info(self.cars, 0, self.numeric_infos)

    def step(self, action):
        cars = self.cars
        if cars is None:
            raise RuntimeError("call reset() before step()")
        if cars.outcome[0] != RUNNING:
            raise RuntimeError("the episode is over; call reset() to start a new one")
        try:  # fast path: any pair of numbers
            acc, turn = action
            outcome = cars.step_one(acc, turn)
        except (TypeError, ValueError):
            outcome = cars.step_one(*as_actions(action, 1)[0])  # raises the error that says what is wrong
        if self.render_mode is not None:
            self._trail.append((float(cars.x[0]), float(cars.y[0])))
            if self.render_mode == "human":
                self.render()
        limit = self.options.max_episode_steps
        truncated = outcome == RUNNING and limit is not None and cars.steps >= limit
        return (cars.observation(0), cars.reward[0].item(), outcome != RUNNING, truncated,
                env_info(cars, 0, self.numeric_infos))

    def scene(self):
        cars = self.cars
        if cars is None:
            return None
        return self.track, cars.x, cars.y, cars.heading, [np.array(self._trail)]


def registered_env(**options) -> MicroRacerEnv:
    """The entry point of `gym.make("league/MicroRacer-v0")`: its time limit is the registry's
    TimeLimit wrapper (so `gym.make(..., max_episode_steps=N)` sets it), not the env's own."""
    return MicroRacerEnv(max_episode_steps=None, **options)
