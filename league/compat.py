"""The thesis' interface (Galletti, sections 3.4-3.6), for the course's existing material.

``Racer``, ``newrun`` and ``metrics_run`` keep the names, positional arguments, attributes and
return values of the original ``tracks.py`` (SPEC "The thesis' Python interface"), so the
thesis' training scripts run with ``tracks.py`` reduced to ``from league.compat import *``
(docs/THESIS_SCRIPTS.md). They are thin layers over
``league.MicroRacerEnv`` and ``league.evaluation``. Like the original, new tracks come from
NumPy's global generator unless a seed is given, so ``np.random.seed(s)`` makes a script
repeatable. The actors may be what the thesis passed: any model that takes a batch of states and
returns the action as its (first) output - a Keras model, a torch module, a function, an object
with ``predict`` - or the toolkit's agents and the path of an ONNX / TorchScript file.
"""
from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from gymnasium.utils import seeding

from league import evaluation, lidar
from league.agents import as_agent
from league.cars import turn_bound
from league.constants import FINISHED, MAX_ACC, MAX_TURN, RUNNING
from league.env import MicroRacerEnv
from league.track import PeriodicSpline, Track, grid_of_map


def global_seed() -> int:
    """A seed drawn from NumPy's global generator: where the thesis drew its tracks from."""
    return int(np.random.randint(0, 2**32, dtype=np.int64))


def _option(name: str, doc: str, field: str | None = None) -> property:
    """An option of the env, writable as the original's attribute: the next reset (the track's
    options) or the next step (tstep, turn_limit, low_speed_termination) uses the new value."""
    field = field or name

    def write(self, value):
        self.env.options = replace(self.env.options, **{field: value})  # checked as when a Racer is made
        self._sync_cars()

    return property(lambda self: getattr(self.env.options, field), write, doc=doc)


def _physics(name: str, doc: str) -> property:
    """A number of the car's physics that the original keeps per racer; the next step uses it."""
    def write(self, value):
        if not np.isfinite(value):
            raise ValueError(f"{name} must be a finite number, got {value!r}")
        self._physics[name] = float(value)
        self._sync_cars()

    return property(lambda self: self._physics[name], write, doc=doc)


def _car(name: str, doc: str) -> property:
    """The car's state; a written value is where the next step starts from, as in the original."""
    def write(self, value):
        getattr(self._cars(), name)[0] = value

    return property(lambda self: float(getattr(self._cars(), name)[0]), write, doc=doc)


def _drawn(name: str, read, doc: str) -> property:
    """What reset draws; written, it is kept until the next reset (the simulation does not read
    it, as in the original)."""
    def get(self):
        return self._written[name] if name in self._written else read(self._track())

    def write(self, value):
        self._written[name] = value

    return property(get, write, doc=doc)


def thesis_obs_pos(track: Track) -> np.ndarray | list:
    """The original's `obs_pos`: a row [x1, x2, y1, y2] per obstacle (its two ends), `[]` without."""
    if not len(track.obstacles):
        return []
    return track.obstacles.transpose(0, 2, 1).reshape(-1, 4)


class Racer:
    """The thesis' environment object: ``reset() -> state``, ``step(action) -> (state, reward, done)``.

    ``Racer(obstacles=True, turn_limit=True, chicanes=True, low_speed_termination=True)``, in
    this positional order, as the thesis' scripts call it. The state is the compact observation
    ``[direction, left, max, right, speed]`` (float32, shape (5,)).

    ``step`` returns, as the original does:

    * on a crash (off road), a wrong direction or too slow: ``(np.array([0]), -3.0, True)``; the
      thesis' scripts tell such a failure by ``done and len(state) < 5`` and store it as terminal;
    * on a completed lap: the full state, the step's reward and ``True``;
    * otherwise the full state, the reward and ``False``. The original has no time limit; here
      an episode also ends (full state, ``done`` true, ``completation`` 0) after 4000 steps
      (``max_episode_steps``), which no lap at the lowest allowed speed reaches.

    ``reset(shared_map=(cs, map, obs_pos, init_v))`` races the track another racer reset on, at
    that initial speed (the values of its ``cs``, ``map``, ``obs_pos`` and ``sinit_v``).

    Attributes of the original, all writable with the original's effect: ``curves``,
    ``track_width``, ``obstacles_number``, ``obstacles`` and ``chicanes`` shape the next track
    (from the next ``reset``); ``tstep``, ``max_acc``, ``max_turn``, ``turn_limit`` and
    ``low_speed_termination`` act from the next step. After ``reset``: ``cs`` / ``csin`` /
    ``csout`` (the mid-line and border splines; ``cs`` of the angle in [0, 2 pi], the borders
    of their polar angle), ``map`` (the 1300 x 1300 boolean grid of cells a car may occupy; a
    new map assigned to it is where the car drives from the next step), ``obs_pos`` (a row
    ``[x1, x2, y1, y2]`` per obstacle, ``[]`` without obstacles), ``carx``, ``cary``, ``carvx``,
    ``carvy`` (velocity), ``cartheta`` (polar angle) (written: where the next step starts),
    ``done``, ``completation`` (0 running, 1 lap completed, 2 off road, 3 wrong direction,
    4 too slow), ``sinit_v`` (initial speed) and, after a step, ``max_turnrad`` (that step's
    turn bound). ``cs``, ``csin``, ``csout``, ``obs_pos`` and the last four are records, as in
    the original: written, they keep the value until ``reset`` or ``step`` sets them.

    Beyond the original: ``seed`` (keyword) seeds the first ``reset`` and the later ones
    continue its stream, apart from NumPy's global generator; other keyword options of
    ``league.MicroRacerEnv`` (``tstep``, ``curves``...) are passed on; ``info`` holds the last
    step's details (outcome, progress, time, distance, speed) and ``track`` the league Track.
    """

    curves = _option("curves", "control points of the mid-line")
    tstep = _option("tstep", "seconds per step")
    track_width = _option("track_width", "world units")
    obstacles_number = _option("obstacles_number", "obstacles per track, when obstacles are on", "n_obstacles")
    obstacles = _option("obstacles", "obstacles on the track")
    turn_limit = _option("turn_limit", "turn limiter: the faster, the smaller the largest turn")
    chicanes = _option("chicanes", "a chicane on the track")
    low_speed_termination = _option("low_speed_termination", "the episode ends below speed 0.05")
    max_acc = _physics("max_acc", "speed gained per second at full throttle (world units / s^2)")
    max_turn = _physics("max_turn", "largest turn of a step (rad)")
    carx = _car("x", "x of the car (world units)")
    cary = _car("y", "y of the car (world units)")
    cartheta = _car("theta", "polar angle of the car around the origin (rad)")
    cs = _drawn("cs", lambda track: track.midline, "the mid-line spline")
    csin = _drawn("csin", lambda track: track.inner, "the inner border's spline")
    csout = _drawn("csout", lambda track: track.outer, "the outer border's spline")
    obs_pos = _drawn("obs_pos", thesis_obs_pos, "the obstacles: a row [x1, x2, y1, y2] each, [] without")

    def __init__(self, obstacles: bool = True, turn_limit: bool = True, chicanes: bool = True,
                 low_speed_termination: bool = True, *, seed: int | None = None, **env_options):
        self.env = MicroRacerEnv(obstacles=obstacles, turn_limit=turn_limit, chicanes=chicanes,
                                 low_speed_termination=low_speed_termination, observation="compact", **env_options)
        self._seeded = seed is not None
        if self._seeded:
            self.env.np_random, _ = seeding.np_random(seed)
        self._physics = {"max_acc": MAX_ACC, "max_turn": MAX_TURN}
        self._written: dict[str, Any] = {}  # values written over what reset drew (cs, map, ...)
        self.info: dict = {}
        self.done = False
        self.completation = RUNNING
        self.sinit_v: float | None = None
        self.max_turnrad = MAX_TURN

    def reset(self, shared_map: tuple | None = None) -> np.ndarray:
        options = None
        if shared_map is not None:
            cs, grid, obs_pos, init_v = shared_map
            options = {"track": self._shared_track(cs, grid, obs_pos), "initial_speed": float(init_v)}
        state, self.info = self.env.reset(seed=None if self._seeded else global_seed(), options=options)
        self._sync_cars()
        self._written = {}
        self.done, self.completation = False, RUNNING
        self.sinit_v = float(self.info["speed"])
        self.max_turnrad = self.max_turn
        return state

    def step(self, action) -> tuple[np.ndarray, float, bool]:
        acc, turn = np.asarray(action, dtype=np.float32).reshape(2)
        self.max_turnrad = turn_bound(self._cars(), 0, float(acc))
        state, reward, terminated, truncated, self.info = self.env.step((acc, turn))
        self.done = bool(terminated or truncated)
        self.completation = int(self.env.cars.outcome[0])
        if terminated and self.completation != FINISHED:
            return np.array([0]), reward, True  # the original's failure state
        return state, reward, self.done

    def _sync_cars(self) -> None:
        """The car's physics numbers from the options and the racer's own (they may have been written)."""
        cars, options = self.env.cars, self.env.options
        if cars is not None:
            cars.tstep, cars.turn_limit, cars.low_speed_termination = (
                options.tstep, options.turn_limit, options.low_speed_termination)
            cars.max_acc, cars.max_turn = self._physics["max_acc"], self._physics["max_turn"]

    def _shared_track(self, cs: PeriodicSpline, grid: np.ndarray, obs_pos) -> Track:
        """The track of another racer's ``(cs, map, obs_pos)``, rebuilt from the spline's control points."""
        if not isinstance(cs, PeriodicSpline):
            raise TypeError(f"shared_map[0] must be another Racer's cs (its mid-line spline), got {type(cs).__name__}")
        # Each cubic piece's constant term is the spline's value at its knot: the control points.
        points = np.vstack([cs.c[-1], cs.c[-1][:1]])
        rows = np.asarray(obs_pos, dtype=np.float64).reshape(-1, 4)  # [x1, x2, y1, y2] per obstacle
        track = Track(cs.x, points, self.track_width, rows.reshape(-1, 2, 2).transpose(0, 2, 1))
        if not np.array_equal(track.valid, np.asarray(grid, dtype=bool)):
            raise ValueError("shared_map's map is not the map of its cs and obs_pos: pass another Racer's "
                             "(racer.cs, racer.map, racer.obs_pos, racer.sinit_v) after its reset(), unchanged, "
                             "to a Racer with the same track_width")
        return track

    def _cars(self):
        if self.env.cars is None:
            raise RuntimeError("call reset() before reading or setting the car's state")
        return self.env.cars

    @property
    def track(self) -> Track | None:
        return self.env.track

    @property
    def map(self) -> np.ndarray:
        """The cells a car may occupy (bool, 1300 x 1300, read-only: assign a new map to change it)."""
        return self._written["map"] if "map" in self._written else self._track().valid

    @map.setter
    def map(self, value: np.ndarray) -> None:
        if self.env.cars is not None:  # before the first reset, as in the original, reset replaces it
            self.env.cars.set_grid(0, grid_of_map(value, self._track().grid & lidar.ROAD_BIT))
        self._written["map"] = value

    @property
    def carvx(self) -> float:
        cars = self._cars()
        return float(cars.speed[0] * np.cos(cars.heading[0]))

    @carvx.setter
    def carvx(self, value: float) -> None:
        self._set_velocity(float(value), self.carvy)

    @property
    def carvy(self) -> float:
        cars = self._cars()
        return float(cars.speed[0] * np.sin(cars.heading[0]))

    @carvy.setter
    def carvy(self, value: float) -> None:
        self._set_velocity(self.carvx, float(value))

    def _set_velocity(self, vx: float, vy: float) -> None:
        cars = self._cars()  # the original keeps the velocity; the core, its speed and heading
        cars.speed[0], cars.heading[0] = np.hypot(vx, vy), np.arctan2(vy, vx)

    def _track(self) -> Track:
        if self.env.track is None:
            raise RuntimeError("call reset() before reading the track")
        return self.env.track


def newrun(actors: Sequence[Any], obstacles: bool = True, turn_limit: bool = True, chicanes: bool = True,
           low_speed_termination: bool = True, *, seed: int | None = None, names: Sequence[str] | None = None,
           show: bool = True, save: str | os.PathLike | None = None, **env_options) -> evaluation.RaceResult:
    """The thesis' race: all actors on one track, printed classification and an animation.

    ``seed`` fixes the track; without it every call draws a new one from NumPy's global
    generator, as the thesis did (the seed is printed, to race that track again).
    ``save="race.gif"`` writes the animation; ``show`` opens a window when a display is
    available. Returns the RaceResult.
    """
    from league import render

    if seed is None:
        seed = global_seed()
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
                chicanes: bool = True, low_speed_termination: bool = True, *, seed: int | None = None,
                verbose: bool = True, **env_options) -> evaluation.MetricsResult:
    """The thesis' evaluation run: ``runs_num`` episodes, printed one by one, then the totals.

    Without ``seed`` every call meets new tracks, drawn from NumPy's global generator as in the
    thesis (the run's seed is in ``result.settings["seed"]``). With one, it is
    ``league.evaluation.metrics_run(as_agent(actor), episodes=runs_num, seed=seed, ...)``: the
    same tracks for every agent.
    """

    result = evaluation.metrics_run(as_agent(actor), episodes=runs_num, seed=global_seed() if seed is None else seed,
                                    obstacles=obstacles, turn_limit=turn_limit, chicanes=chicanes,
                                    low_speed_termination=low_speed_termination, **env_options)
    if verbose:  # after the run: its episodes run together and end in any order
        for i, episode in enumerate(result.episodes):
            print(f"episode {i}: steps {episode.steps}, return {episode.episode_return:.3f}, "
                  f"mean speed {episode.mean_speed:.3f}, {evaluation.OUTCOME_TEXT[episode.outcome]}")
        print(f"completed {result.completed} / {result.episodes_total}, mean return {result.mean_return:.3f}, "
              f"mean steps {result.mean_steps:.1f}, mean speed {result.mean_speed:.3f}")
    return result


__all__ = ["Racer", "as_agent", "metrics_run", "newrun"]
