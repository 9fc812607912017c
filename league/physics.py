"""Car physics: environment options, episode starts (and their cache) and the batched car state.

The step rules themselves (SPEC 'Car') run in the compiled core, `league.lidar.CarBatch`, with
the numbers of `league.constants`; this module holds the options and the bookkeeping that the
environments and evaluations share.
"""
from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, fields

import numpy as np
from gymnasium.utils import seeding

from league import lidar
from league.constants import (  # noqa: F401 (FINISHED, MAX_ACC, MAX_TURN, OUTCOMES, RUNNING: re-exported for the envs)
    COMPACT_DIM, FINISHED, LIDAR_DIM, MAX_ACC, MAX_TURN, OUTCOMES, RUNNING, TSTEP, TURN_LIMIT_COEFF,
)
from league.track import (
    CURVES, CURVES_RANGE, MAX_TRACK_WIDTH, N_OBSTACLES, N_OBSTACLES_RANGE, TRACK_WIDTH, Track, generate_track,
)

START_SPEED_MAX = 0.5  # initial speed ~ U(0, 0.5)
START_SPEED_FLOOR = 0.07  # with low-speed termination on
MAX_EPISODE_STEPS = 4000  # 160 s: a lap at the lowest allowed speed (0.05) still fits
OBSERVATIONS = ("compact", "lidar")
# What a course can use besides the track's own ranges (league.track CURVES_RANGE, N_OBSTACLES_RANGE):
# beyond these an episode makes a huge replay.
EPISODE_STEPS_RANGE = (1, 20_000)  # a lap at the lowest speed (0.05) fits even at tstep 0.01
TSTEP_RANGE = (0.01, 0.2)  # seconds
# Episode starts kept per process by `episode_start`. A track holds its 1300 x 1300 map
# (1.69 MB) once a car has driven on it, so the cache holds at most ~220 MB.
TRACK_CACHE_SIZE = 128


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
    # None: no limit of the env's own (gym.make's TimeLimit keeps time)
    max_episode_steps: int | None = MAX_EPISODE_STEPS

    def __post_init__(self):
        for name in ("obstacles", "chicanes", "turn_limit", "low_speed_termination"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.observation not in OBSERVATIONS:
            raise ValueError(f"observation must be one of {OBSERVATIONS}, got {self.observation!r}")
        _check_int("curves", self.curves, *CURVES_RANGE)
        _check_int("n_obstacles", self.n_obstacles, *N_OBSTACLES_RANGE)
        if self.max_episode_steps is not None:
            _check_int("max_episode_steps", self.max_episode_steps, *EPISODE_STEPS_RANGE)
        if not 0 < self.track_width <= MAX_TRACK_WIDTH:
            raise ValueError(f"track_width must be in (0, {MAX_TRACK_WIDTH}] world units, got {self.track_width!r}")
        if not TSTEP_RANGE[0] <= self.tstep <= TSTEP_RANGE[1]:
            raise ValueError(f"tstep must be in [{TSTEP_RANGE[0]}, {TSTEP_RANGE[1]}] seconds, got {self.tstep!r}")

    @classmethod
    def from_kwargs(cls, caller: str = "RaceOptions", /, **kwargs) -> RaceOptions:
        """The options from keyword arguments; an unknown one raises Python's own TypeError for `caller()`.

        Tools probe envs with extra arguments and recognise that wording (torchrl passes
        ``frameskip=1`` and falls back on "unexpected keyword argument 'frameskip'").
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - known)
        if unknown:
            raise TypeError(f"{caller}() got an unexpected keyword argument {unknown[0]!r}; "
                            f"valid options: {sorted(known)}")
        return cls(**kwargs)

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def obs_dim(self) -> int:
        return COMPACT_DIM if self.observation == "compact" else LIDAR_DIM

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

    def start_key(self) -> tuple:
        """The options that decide an episode's track and initial speed (what `episode_start` keys on)."""
        return tuple(getattr(self, name) for name in START_OPTIONS)


START_OPTIONS = ("curves", "track_width", "chicanes", "obstacles", "n_obstacles", "low_speed_termination")


def episode_start(seed: int, options: RaceOptions) -> tuple[Track, float]:
    """The track and initial speed that `MicroRacerEnv(**options).reset(seed=seed)` draws.

    Kept in this process's bounded cache (`TRACK_CACHE_SIZE` starts, least recently used out
    first), so evaluations with the same seeds (every submission of a course) share their tracks.
    """
    return _cached_start(int(seed), options.start_key())


def _draw_start(seed: int, key: tuple) -> tuple[Track, float]:
    options = RaceOptions(**dict(zip(START_OPTIONS, key)))
    rng, _ = seeding.np_random(seed)  # as Gymnasium's Env.reset(seed=seed)
    return options.new_track(rng), options.initial_speed(rng)


_cached_start = functools.lru_cache(maxsize=TRACK_CACHE_SIZE)(_draw_start)


def set_track_cache_size(size: int) -> None:
    """Bound `episode_start`'s cache to `size` starts (0 keeps none); empties it."""
    global _cached_start
    _check_int("size", size, 0, 4096)  # each start may hold a 1.69 MB map
    _cached_start = functools.lru_cache(maxsize=size)(_draw_start)


def track_cache_info() -> tuple:
    """Hits, misses, size and bound of `episode_start`'s cache."""
    return _cached_start.cache_info()


def _check_int(name, value, minimum, maximum):
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not minimum <= value <= maximum:
        raise ValueError(f"{name} must be an integer in [{minimum}, {maximum}], got {value!r}")


def new_cars(n: int, options: RaceOptions) -> lidar.CarBatch:
    """N cars with the physics options; start them with `start_cars` or `place_car`."""
    return lidar.CarBatch(n, tstep=options.tstep, turn_limit=options.turn_limit,
                          low_speed_termination=options.low_speed_termination,
                          compact=options.observation == "compact")


def start_cars(cars: lidar.CarBatch | None, n: int, track: Track, options: RaceOptions, speed: float) -> lidar.CarBatch:
    """N cars at the start of one track (reusing `cars` when given)."""
    cars = cars or new_cars(n, options)
    x, y = track.start_position
    cars.reset(x, y, track.start_heading, speed, grid=track.grid)
    return cars


def turn_bound(cars: lidar.CarBatch, c: int, acc: float) -> float:
    """The largest turn (rad) of car c's next step with acceleration action `acc` (SPEC 'Car'),
    with the batch's physics numbers.

    The compiled core applies the same rule; the thesis' interface reports it as `max_turnrad`.
    """
    new_speed = max(0.0, float(cars.speed[c]) + min(1.0, max(-1.0, acc)) * cars.max_acc * cars.tstep)
    if cars.turn_limit and new_speed > 0:
        return min(cars.max_turn, TURN_LIMIT_COEFF * cars.tstep / new_speed)
    return cars.max_turn


def place_car(cars: lidar.CarBatch, c: int, track: Track, speed: float) -> None:
    """Start car c's own episode at the start of its track."""
    x, y = track.start_position
    cars.place(c, track.grid, x, y, track.start_heading, speed)


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
