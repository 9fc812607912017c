"""Random closed tracks: a spline mid-line, two borders, obstacles and the 1300 x 1300 grid map.

`generate_track(rng)` draws every random choice from the given `numpy.random.Generator` and
returns an immutable `Track`. A track is fully determined by its control points and obstacle
segments (`Track.to_dict()`); the splines and the map are re-derived from them, so a saved
track rebuilds bit for bit (`Track.from_dict`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np

from league import lidar
from league.constants import (
    BORDER_SAMPLES_PER_CURVE, CELLS_PER_UNIT, CHICANE_ADDED_POINTS, CHICANE_INNER, CHICANE_OUTER, CHICANE_PUSH, CURVES,
    CURVES_RANGE, GRID, MAP_EXTENT, MAX_DRAWS, MAX_TRACK_WIDTH, N_OBSTACLES, N_OBSTACLES_RANGE, OBSTACLE_LENGTH, ORIGIN,
    RASTER_ANGLES, TRACK_CACHE_SIZE, TRACK_FORMAT_VERSION, TRACK_WIDTH,
)

MAX_CONTROL_POINTS = CURVES_RANGE[1] + CHICANE_ADDED_POINTS


class TrackGenerationError(RuntimeError):
    """No valid track could be drawn with these parameters."""


@dataclass(frozen=True, eq=False)
class Track:
    """An immutable track: mid-line control points, width and obstacle segments.

    Derived data (splines, borders, grid map) is computed on first use and cached.
    Maps are read-only numpy arrays indexed [i, j] with i = int(x*500)+650, j = int(y*500)+650.
    """

    control_theta: np.ndarray  # (n,) strictly increasing angles, 0 ... 2*pi
    control_points: np.ndarray  # (n, 2) mid-line control points; last equals first
    width: float = TRACK_WIDTH
    obstacles: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))  # (k, 2 ends, xy)

    def __post_init__(self):
        for name in ("control_theta", "control_points", "obstacles"):
            array = np.array(getattr(self, name), dtype=np.float64)
            array.flags.writeable = False
            object.__setattr__(self, name, array)

    # -- geometry -------------------------------------------------------------------------
    @cached_property
    def midline(self) -> PeriodicSpline:
        """Mid-line as a periodic spline of the control angle theta in [0, 2*pi]."""
        return PeriodicSpline(self.control_theta, self.control_points)

    @cached_property
    def _borders(self) -> np.ndarray:
        """(2, samples, 2): the inner and outer border points, half a width either side of the mid-line."""
        theta = _border_samples(len(self.control_theta))
        half = self.width / 2
        return _read_only(lidar.offset_points(self.midline.x, self.midline.c, theta, np.array([[half, -half]])))

    @cached_property
    def _border_angles(self) -> np.ndarray:
        """(2, samples): the border points' polar angles, unwrapped."""
        borders = self._borders
        return np.array([lidar.unwrap(phi) for phi in np.arctan2(borders[..., 1], borders[..., 0])])

    @cached_property
    def inner(self) -> PeriodicSpline:
        """Inner border as a periodic spline of its own polar angle."""
        return _polar_spline(self._border_angles[0], self._borders[0])

    @cached_property
    def outer(self) -> PeriodicSpline:
        """Outer border as a periodic spline of its own polar angle."""
        return _polar_spline(self._border_angles[1], self._borders[1])

    @property
    def inner_border(self) -> np.ndarray:
        return _closed_polyline(self.inner)

    @property
    def outer_border(self) -> np.ndarray:
        return _closed_polyline(self.outer)

    @cached_property
    def raster_segments(self) -> tuple[np.ndarray, np.ndarray]:
        """Inner and outer border points at the map's rasterisation angles."""
        return self.inner(RASTER_PHI, polar=True), self.outer(RASTER_PHI, polar=True)

    @property
    def start_position(self) -> tuple[float, float]:
        x, y = self.control_points[0]
        return float(x), float(y)

    @property
    def start_heading(self) -> float:
        """The race runs clockwise: along minus the mid-line's derivative at theta = 0."""
        dx, dy = self.midline(0.0, 1)
        return float(np.arctan2(-dy, -dx))

    @cached_property
    def length(self) -> float:
        theta = np.linspace(0, 2 * np.pi, 4001)
        return float(np.sum(np.hypot(*np.diff(self.midline(theta), axis=0).T)))

    # -- maps -----------------------------------------------------------------------------
    @cached_property
    def grid(self) -> np.ndarray:
        """uint8 (1300, 1300) map whose bits are the layers VALID, FREE and ROAD (compiled core's view)."""
        inner, outer = self.raster_segments
        grid = lidar.rasterise_track(
            np.ascontiguousarray(inner), np.ascontiguousarray(outer),
            np.ascontiguousarray(self.obstacles.reshape(-1, 2, 2)), obstacle_half_size(self.width),
        )
        return _read_only(grid)

    @cached_property
    def valid(self) -> np.ndarray:
        """bool (1300, 1300): cells a car may occupy (road minus obstacles)."""
        return _read_only((self.grid & lidar.VALID_BIT).astype(bool))

    @cached_property
    def free(self) -> np.ndarray:
        """bool (1300, 1300): cells the lidar sees through (the cell and its 4 neighbours valid)."""
        return _read_only((self.grid & lidar.FREE_BIT).astype(bool))

    @cached_property
    def obstacle_cells(self) -> np.ndarray:
        """bool (1300, 1300): road cells made invalid by obstacles."""
        return _read_only((self.grid & (lidar.ROAD_BIT | lidar.VALID_BIT)) == lidar.ROAD_BIT)

    def with_obstacles(self, obstacles: np.ndarray) -> Track:
        """The same track with these obstacle segments (the mid-line and borders are reused)."""
        track = Track(self.control_theta, self.control_points, self.width, obstacles)
        for name in ("midline", "_borders", "_border_angles", "inner", "outer", "raster_segments"):
            if name in self.__dict__:  # cached geometry does not depend on obstacles
                track.__dict__[name] = self.__dict__[name]
        return track

    def fits_grid(self) -> bool:
        """True when every outer border point lies inside the map."""
        return lidar.inside_grid(self.raster_segments[1])

    def is_valid_position(self, x: float, y: float) -> bool:
        i, j = cell_of(x, y)
        return 0 <= i < GRID and 0 <= j < GRID and bool(self.grid[i, j] & lidar.VALID_BIT)

    # -- persistence ----------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Compact, JSON-safe form (floats round-trip exactly through json)."""
        return {
            "version": TRACK_FORMAT_VERSION,
            "width": float(self.width),
            "control_theta": self.control_theta.tolist(),
            "control_points": self.control_points.tolist(),
            "obstacles": self.obstacles.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> Track:
        """The track of a `to_dict` form, checked before anything is derived from it (it may come from
        anyone: a replay file, a request to the server): counts, shapes, finite numbers inside the map.

        Raises:
            ValueError: not a track of this format, with what is wrong.
        """
        if not isinstance(data, dict):
            raise ValueError(f"a track is a JSON object, got {type(data).__name__}")
        if data.get("version") != TRACK_FORMAT_VERSION:
            raise ValueError(f"unsupported track format version {data.get('version')!r}; "
                             f"expected {TRACK_FORMAT_VERSION}")
        n = _count(data, "control_theta", CURVES_RANGE[0], MAX_CONTROL_POINTS)
        theta = _numbers(data, "control_theta", (n,), 2 * np.pi)
        points = _numbers(data, "control_points", (n, 2), MAP_EXTENT)
        obstacles = _numbers(data, "obstacles", (_count(data, "obstacles", *N_OBSTACLES_RANGE), 2, 2), MAP_EXTENT)
        width = data.get("width")
        if isinstance(width, bool) or not isinstance(width, (int, float)) or not 0 < width <= MAX_TRACK_WIDTH:
            raise ValueError(f"width must be a number in (0, {MAX_TRACK_WIDTH}], got {width!r}")
        if theta[0] != 0 or not np.isclose(theta[-1], 2 * np.pi, rtol=0, atol=1e-9) or np.any(np.diff(theta) <= 0):
            raise ValueError("control_theta must increase strictly from 0 to 2*pi")
        if not np.array_equal(points[0], points[-1]):
            raise ValueError("the last control point must equal the first (the mid-line is closed)")
        return cls(theta, points, float(width), obstacles)

    def __reduce__(self):
        return (Track.from_dict, (self.to_dict(),))  # compact: the maps are re-derived

    def __eq__(self, other) -> bool:
        if not isinstance(other, Track):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash((self.control_points.tobytes(), self.obstacles.tobytes(), self.width))


def _count(data: dict, key: str, least: int, most: int) -> int:
    """The length of the list data[key], checked before its items are read."""
    value = data.get(key)
    if not isinstance(value, list):
        raise ValueError(f"{key} must be a list of {least} to {most} items" + (" (missing)" if value is None else ""))
    if not least <= len(value) <= most:
        raise ValueError(f"{key} must be a list of {least} to {most} items, got {len(value)}")
    return len(value)


def _numbers(data: dict, key: str, shape: tuple[int, ...], bound: float) -> np.ndarray:
    """data[key] as a float array of `shape`, numbers only, each within [-bound, bound]."""
    value = data.get(key)
    if not isinstance(value, list) or len(value) != shape[0]:  # before numpy reads it
        raise ValueError(f"{key} must be a list of {shape[0]} items")
    if not value:
        return np.zeros(shape)
    try:
        array = np.array(value)
    except ValueError as error:  # ragged
        raise ValueError(f"{key} must be numbers of shape {shape}") from error
    if array.shape != shape or array.dtype.kind not in "iuf":
        raise ValueError(f"{key} must be numbers of shape {shape}, got shape {array.shape} of {array.dtype}")
    array = array.astype(np.float64)
    if not np.all(np.abs(array) <= bound):  # NaN fails too
        raise ValueError(f"{key} must be finite numbers within [-{bound:g}, {bound:g}]")
    return array


class PeriodicSpline:
    """A periodic cubic spline through (x[k], y[k]), y[-1] == y[0], called like scipy's:
    ``spline(t, nu=0)`` gives the values (or nu-th derivatives) at t, shape t.shape + (2,).

    It is scipy.interpolate.CubicSpline(x, y, bc_type="periodic") bit for bit, built and
    evaluated in the compiled core (league/lidar.pyx says how).
    """

    def __init__(self, x: np.ndarray, y: np.ndarray):
        self.x = _read_only(np.array(x, dtype=np.float64))
        self.c = _read_only(lidar.periodic_spline(self.x, np.ascontiguousarray(y, dtype=np.float64)))

    def __call__(self, t, nu: int = 0, polar: bool = False) -> np.ndarray:
        """polar: t are polar angles, taken modulo 2*pi from the spline's start (x[0]) first."""
        return lidar.evaluate_spline(self.x, self.c, t, nu, polar)


def cell_of(x, y):
    """World coordinates -> grid cell (i, j); int() truncates toward zero."""
    return int(x * CELLS_PER_UNIT) + ORIGIN, int(y * CELLS_PER_UNIT) + ORIGIN


def grid_of_map(valid: np.ndarray, road: np.ndarray) -> np.ndarray:
    """The grid map (as `Track.grid`) of a bool map of the cells a car may occupy: FREE where
    the cell and its 4 neighbours are valid (none beyond the edge), ROAD from `road` (drawing only)."""
    valid = np.asarray(valid, dtype=bool)
    if valid.shape != (GRID, GRID):
        raise ValueError(f"a map must have shape ({GRID}, {GRID}), like Track.valid; got {valid.shape}")
    free = np.zeros_like(valid)
    inner = valid[1:-1, 1:-1]
    free[1:-1, 1:-1] = inner & valid[:-2, 1:-1] & valid[2:, 1:-1] & valid[1:-1, :-2] & valid[1:-1, 2:]
    grid = valid * np.uint8(lidar.VALID_BIT) | free * np.uint8(lidar.FREE_BIT)
    return grid | np.asarray(road, dtype=bool) * np.uint8(lidar.ROAD_BIT)


def obstacle_half_size(width: float) -> int:
    return int(width * CELLS_PER_UNIT / 4)


def generate_track(
    rng: np.random.Generator,
    *,
    curves: int = CURVES,
    track_width: float = TRACK_WIDTH,
    chicanes: bool = True,
    obstacles: bool = True,
    n_obstacles: int = N_OBSTACLES,
) -> Track:
    """Draw a random track (SPEC 'Track'); redraw when it leaves the grid."""
    if not CURVES_RANGE[0] <= curves <= CURVES_RANGE[1]:
        raise ValueError(f"curves must be in [{CURVES_RANGE[0]}, {CURVES_RANGE[1]}], got {curves}")
    if not 0 < track_width <= MAX_TRACK_WIDTH:
        raise ValueError(f"track_width must be in (0, {MAX_TRACK_WIDTH}], got {track_width}")
    if not N_OBSTACLES_RANGE[0] <= n_obstacles <= N_OBSTACLES_RANGE[1]:
        raise ValueError(f"n_obstacles must be in [{N_OBSTACLES_RANGE[0]}, {N_OBSTACLES_RANGE[1]}], got {n_obstacles}")
    candidates = (Track(*_midline_controls(rng, curves, chicanes), track_width) for _ in range(MAX_DRAWS))
    track = first_fitting(candidates)
    if obstacles and n_obstacles:
        track = track.with_obstacles(_draw_obstacles(rng, track, n_obstacles))
    return track


def first_fitting(candidates) -> Track:
    """The first candidate whose borders are functions of the polar angle and that fits the grid."""
    for track in candidates:
        if _borders_are_star_shaped(track) and track.fits_grid():
            return track
    raise TrackGenerationError(f"no track fitted the grid in {MAX_DRAWS} draws; try a narrower track_width")


# -- mid-line ------------------------------------------------------------------------------
def _midline_controls(rng: np.random.Generator, curves: int, chicanes: bool):
    theta, unit = _control_angles(curves)
    radius = _smoothed_radii(rng.random(curves))
    points = unit * radius[:, None]
    if chicanes:
        theta, points = _add_chicane(rng, curves, radius, points)
    points[-1] = points[0]  # exact periodicity for the spline
    return theta, points


# Small caches of what every track of a shape shares, keyed by counts that from_dict and
# generate_track bound; bounded anyway, as every cache of code the server runs.
@lru_cache(maxsize=CURVES_RANGE[1])
def _control_angles(curves: int) -> tuple[np.ndarray, np.ndarray]:
    """The control angles and their unit vectors (cos, sin): the same for every track."""
    theta = 2 * np.pi * np.linspace(0, 1, curves)
    return _read_only(theta), _read_only(_polar(theta, 1.0))


@lru_cache(maxsize=256)
def _chicane_angles(curves: int, c: int) -> tuple[np.ndarray, np.ndarray]:
    """The control angles with control point c replaced by the chicane's five, and their unit vectors."""
    theta = _control_angles(curves)[0]
    delta = abs(theta[c - 1] - theta[c])
    offsets = np.array([-CHICANE_OUTER, -CHICANE_INNER, 0.0, CHICANE_INNER, CHICANE_OUTER]) * delta
    new_theta = np.concatenate([theta[:c], theta[c] + offsets, theta[c + 1:]])
    return _read_only(new_theta), _read_only(_polar(new_theta, 1.0))


def _smoothed_radii(draws: np.ndarray) -> np.ndarray:
    """SPEC smoothing, in index order and cyclic (each step sees the ones before it)."""
    var = draws.tolist()  # 20 scalars, sequentially dependent: Python floats are the fastest here
    n = len(var)
    for i in range(n):
        prev, nxt = var[i - 1], var[(i + 1) % n]
        s = 2 * var[i] - (prev + nxt)
        if s > 1:
            var[i] = (1 + prev + nxt) / 2
        elif s < -1:
            var[i] = (prev + nxt - 1) / 2
    radius = 0.5 * np.array(var) + 0.7
    radius[-1] = radius[0]
    return radius


def _polar(theta, radius) -> np.ndarray:
    return np.stack([np.cos(theta) * radius, np.sin(theta) * radius], axis=-1)


def _add_chicane(rng, curves, radius, points):
    """Replace control point c by five points on the chord from c-1 to c+1, inner pair pushed apart."""
    c = int(rng.integers(1, curves - 2))  # uniform in [1, curves - 3]
    new_theta, unit = _chicane_angles(curves, c)
    new_radius = np.concatenate([radius[:c], np.full(5, radius[c]), radius[c + 1:]])
    new_points = unit * new_radius[:, None]
    chicane = _on_chord(unit[c:c + 5], points[c - 1], points[c + 1])
    push = np.array([1 + CHICANE_PUSH, 1 - CHICANE_PUSH])
    if rng.random() >= 0.5:
        push = push[::-1]
    chicane[1] *= push[0]
    chicane[3] *= push[1]
    new_points[c:c + 5] = chicane
    return new_theta, new_points


def _on_chord(direction, a, b) -> np.ndarray:
    """Intersect the rays from the origin along the unit vectors `direction` with the line through a and b."""
    chord = b - a
    # Solve t * direction = a + s * chord for t: t = cross(a, chord) / cross(direction, chord).
    t = (a[0] * chord[1] - a[1] * chord[0]) / (direction[:, 0] * chord[1] - direction[:, 1] * chord[0])
    return direction * t[:, None]


# -- borders -------------------------------------------------------------------------------
def _borders_are_star_shaped(track: Track) -> bool:
    """Each border must be a function of its polar angle (strictly increasing angles)."""
    return all(lidar.strictly_increasing(phi) for phi in track._border_angles)


def _polar_spline(phi: np.ndarray, points: np.ndarray) -> PeriodicSpline:
    points = points.copy()
    points[-1] = points[0]
    return PeriodicSpline(phi, points)


@lru_cache(maxsize=MAX_CONTROL_POINTS)
def _border_samples(n_controls: int) -> np.ndarray:
    """Mid-line angles at which the borders are placed (SPEC: 6 per control point)."""
    return _read_only(np.linspace(0, 2 * np.pi, BORDER_SAMPLES_PER_CURVE * (n_controls - 1)))


RASTER_PHI = np.arange(RASTER_ANGLES) * (2 * np.pi / RASTER_ANGLES)  # polar angles of the map's segments


def _closed_polyline(spline: PeriodicSpline, samples: int = 720) -> np.ndarray:
    return spline(np.linspace(0, 2 * np.pi, samples + 1), polar=True)


# -- obstacles -----------------------------------------------------------------------------
def _draw_obstacles(rng: np.random.Generator, track: Track, count: int) -> np.ndarray:
    """Obstacle segments along the track, offset inward from the outer border (SPEC 'Obstacles')."""
    slots = count + 2
    u = rng.uniform(2 * np.pi / (2 * slots), 2 * np.pi / slots, size=slots)
    phi = (_slot_starts(slots) + u)[1:count + 1]
    sides = OBSTACLE_SIDES[rng.integers(0, 2, size=count)] * track.width  # rng.choice(OBSTACLE_SIDES): its draws
    angles = np.stack([phi, phi - OBSTACLE_LENGTH], axis=1).ravel()  # each obstacle's two ends
    outer = track.outer
    return lidar.offset_points(outer.x, outer.c, angles, np.repeat(sides, 2)[:, None], True).reshape(count, 2, 2)


OBSTACLE_SIDES = np.array([0.85, 0.15])  # an obstacle's offset from the outer border, in track widths


@lru_cache(maxsize=N_OBSTACLES_RANGE[1] + 2)
def _slot_starts(slots: int) -> np.ndarray:
    return _read_only(np.arange(slots) * (2 * np.pi / slots))


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


# --------------------------------------------------------------------------- episode starts, cached


def episode_start(seed: int, options) -> tuple[Track, float]:
    """The track and initial speed that `MicroRacerEnv(**options).reset(seed=seed)` draws
    (`options` a league.options.RaceOptions).

    Kept in this process's bounded cache (`TRACK_CACHE_SIZE` starts, least recently used out
    first), so evaluations with the same seeds (every submission of a course) share their tracks.
    """
    return _cached_start(int(seed), options.start_options())


def _draw_start(seed: int, options) -> tuple[Track, float]:
    from gymnasium.utils import seeding

    rng, _ = seeding.np_random(seed)  # as Gymnasium's Env.reset(seed=seed)
    return options.new_track(rng), options.initial_speed(rng)


_cached_start = lru_cache(maxsize=TRACK_CACHE_SIZE)(_draw_start)


def set_track_cache_size(size: int) -> None:
    """Bound `episode_start`'s cache to `size` starts (0 keeps none); empties it."""
    global _cached_start
    if not isinstance(size, (int, np.integer)) or isinstance(size, bool) or not 0 <= size <= 4096:
        raise ValueError(f"size must be an integer in [0, 4096], got {size!r}")  # each start may hold a 1.69 MB map
    _cached_start = lru_cache(maxsize=size)(_draw_start)


def track_cache_info() -> tuple:
    """Hits, misses, size and bound of `episode_start`'s cache."""
    return _cached_start.cache_info()
