"""The cars of the compiled core (league.lidar.CarBatch): made with an environment's options, placed
at a track's start, and the actions they take, checked.

The step rules themselves (SPEC 'Car') run in the compiled core with the numbers of
league.constants; the envs, the evaluations and the thesis' interface share these helpers.
"""
from __future__ import annotations

import numpy as np

from league import lidar
from league.constants import TURN_LIMIT_COEFF
from league.options import RaceOptions
from league.track import Track


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
    shape = array.shape
    if shape == (n, 2):
        return array
    if not (n == 1 and shape == (2,)):
        expected = "(2,)" if n == 1 else f"({n}, 2)"
        raise ValueError(f"action must have shape {expected} [acceleration, turn], got shape {shape}")
    return array.reshape(n, 2)
