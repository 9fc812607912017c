"""RaceOptions: every option of a MicroRacer environment, checked, and what it draws at a reset.

The numbers (defaults and ranges) are league.constants'; the step rules run in the compiled core
(league.lidar.CarBatch, made by league.cars).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from league.constants import (
    CURVES, CURVES_RANGE, EPISODE_STEPS_RANGE, MAX_EPISODE_STEPS, MAX_TRACK_WIDTH, N_OBSTACLES, N_OBSTACLES_RANGE,
    OBSERVATION_DIMS, OBSERVATIONS, START_SPEED_FLOOR, START_SPEED_MAX, TRACK_WIDTH, TSTEP, TSTEP_RANGE,
)
from league.track import Track, generate_track

# The options that decide an episode's track and initial speed (what league.track.episode_start keys on).
START_OPTIONS = ("curves", "track_width", "chicanes", "obstacles", "n_obstacles", "low_speed_termination")


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
        return OBSERVATION_DIMS[self.observation]

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

    def episode_start(self, rng: np.random.Generator, reset_options: dict | None = None) -> tuple[Track, float]:
        """An episode's track and initial speed, as every env's reset draws them from its generator:
        `reset(options={"track": track, "initial_speed": v})` gives either instead of drawing it."""
        reset_options = reset_options or {}
        track = reset_options.get("track") or self.new_track(rng)
        speed = reset_options.get("initial_speed")
        return track, self.initial_speed(rng) if speed is None else float(speed)

    def start_options(self) -> RaceOptions:
        """These options with only those that decide a start (`START_OPTIONS`) kept, the others at
        their defaults: the key of league.track.episode_start's cache."""
        return replace(RaceOptions(), **{name: getattr(self, name) for name in START_OPTIONS})


def _check_int(name, value, minimum, maximum):
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not minimum <= value <= maximum:
        raise ValueError(f"{name} must be an integer in [{minimum}, {maximum}], got {value!r}")
