"""Car physics: constants, environment options and the batched car state.

The step rules themselves (SPEC 'Car') run in the compiled core, `league.lidar.CarBatch`;
this module holds the options and the per-race bookkeeping both environments share.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np

from league import lidar
from league.track import CURVES, MAX_TRACK_WIDTH, N_OBSTACLES, TRACK_WIDTH, Track, generate_track

TSTEP = 0.04  # seconds per step
MAX_ACC = 0.1  # world units / s^2 at full throttle
MAX_TURN = np.pi / 6  # rad per step at full lock
CRASH_REWARD = -3.0
START_SPEED_MAX = 0.5  # initial speed ~ U(0, 0.5)
START_SPEED_FLOOR = 0.07  # with low-speed termination on
MAX_EPISODE_STEPS = 4000  # 160 s: a lap at the lowest allowed speed (0.05) still fits
N_RAYS = lidar.N_LIDAR_RAYS

# Outcome codes of the compiled core, by name.
OUTCOMES = lidar.OUTCOME_NAMES
RUNNING, FINISHED = 0, 1
OBSERVATIONS = ("compact", "lidar")


@dataclass(frozen=True)
class RaceOptions:
    """Every option of a MicroRacer environment (all on by default, as in the thesis)."""

    obstacles: bool = True
    chicanes: bool = True
    turn_limit: bool = True
    low_speed_termination: bool = True
    curves: int = CURVES
    track_width: float = TRACK_WIDTH
    n_obstacles: int = N_OBSTACLES
    tstep: float = TSTEP
    observation: str = "compact"
    max_episode_steps: int = MAX_EPISODE_STEPS

    def __post_init__(self):
        for name in ("obstacles", "chicanes", "turn_limit", "low_speed_termination"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.observation not in OBSERVATIONS:
            raise ValueError(f"observation must be one of {OBSERVATIONS}, got {self.observation!r}")
        _check_int("curves", self.curves, 5)
        _check_int("n_obstacles", self.n_obstacles, 0)
        _check_int("max_episode_steps", self.max_episode_steps, 1)
        if not 0 < self.track_width <= MAX_TRACK_WIDTH:
            raise ValueError(f"track_width must be in (0, {MAX_TRACK_WIDTH}] world units, got {self.track_width!r}")
        if not 0 < self.tstep <= 1:
            raise ValueError(f"tstep must be in (0, 1] seconds, got {self.tstep!r}")

    @classmethod
    def from_kwargs(cls, **kwargs) -> RaceOptions:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - known)
        if unknown:
            raise TypeError(f"unknown MicroRacer option(s) {unknown}; valid options: {sorted(known)}")
        return cls(**kwargs)

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def obs_dim(self) -> int:
        return 5 if self.observation == "compact" else N_RAYS + 1

    def new_track(self, rng: np.random.Generator) -> Track:
        return generate_track(
            rng,
            curves=self.curves,
            track_width=self.track_width,
            chicanes=self.chicanes,
            obstacles=self.obstacles,
            n_obstacles=self.n_obstacles,
        )

    def initial_speed(self, rng: np.random.Generator) -> float:
        speed = rng.uniform(0, START_SPEED_MAX)
        return max(speed, START_SPEED_FLOOR) if self.low_speed_termination else speed


def _check_int(name, value, minimum):
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def new_cars(n: int, track: Track, options: RaceOptions) -> lidar.CarBatch:
    """N cars on a track, with the physics options; call `.reset(x, y, heading, speed)` next."""
    if n < 1:
        raise ValueError(f"the number of cars must be >= 1, got {n}")
    return lidar.CarBatch(
        n, track.grid, tstep=options.tstep, max_acc=MAX_ACC, max_turn=MAX_TURN, turn_limit=options.turn_limit,
        low_speed_termination=options.low_speed_termination, compact=options.observation == "compact",
    )


def start_cars(cars: lidar.CarBatch | None, n: int, track: Track, options: RaceOptions, speed: float) -> lidar.CarBatch:
    """Cars at the start of a track (reusing `cars` when it is already on that track)."""
    if cars is None or cars.grid is not track.grid:
        cars = new_cars(n, track, options)
    x, y = track.start_position
    cars.reset(x, y, track.start_heading, speed)
    return cars


def as_actions(action, n: int) -> np.ndarray:
    """Actions as a C-contiguous float32 (n, 2) array, with errors that say what is wrong.

    NaN is rejected by the compiled step itself, before any car moves.
    """
    try:
        array = np.ascontiguousarray(action, dtype=np.float32)
    except (TypeError, ValueError) as error:
        raise ValueError(f"an action must be numbers [acceleration, turn], got {action!r}") from error
    if array.shape != (n, 2) and not (n == 1 and array.shape == (2,)):
        expected = "(2,)" if n == 1 else f"({n}, 2)"
        raise ValueError(f"action must have shape {expected} [acceleration, turn], got shape {array.shape}")
    return array.reshape(n, 2)
