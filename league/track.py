"""Random closed tracks: a spline mid-line, two borders, obstacles and the 1300 x 1300 grid map.

`generate_track(rng)` draws every random choice from the given `numpy.random.Generator` and
returns an immutable `Track`. A track is fully determined by its control points and obstacle
segments (`Track.to_dict()`); the splines and the map are re-derived from them, so a saved
track rebuilds bit for bit (`Track.from_dict`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.interpolate import CubicSpline

from league import lidar

CURVES = 20  # control points of the mid-line
TRACK_WIDTH = 0.04  # world units (1 unit = 1000 m)
MAX_TRACK_WIDTH = 0.08  # wider borders fold on tight bends
N_OBSTACLES = 6
GRID = lidar.GRID_SIZE  # cells per side of the map
CELLS_PER_UNIT = 500  # grid resolution
BORDER_SAMPLES_PER_CURVE = 6  # mid-line samples per control point, for the borders
RASTER_ANGLES = 2000  # inner -> outer segments drawn on the map
OBSTACLE_LENGTH = np.pi / 150  # angular length of an obstacle (rad)
CHICANE_OUTER, CHICANE_INNER = 1 / 3, 1 / 25  # chicane points at theta[c] +- delta * these
CHICANE_PUSH = 0.02  # the chicane's inner pair is pushed apart by +-2 %
MAX_DRAWS = 100  # tracks drawn before giving up (a discarded track is very rare)

FORMAT_VERSION = 1


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
    def midline(self) -> CubicSpline:
        """Mid-line as a periodic spline of the control angle theta in [0, 2*pi]."""
        return CubicSpline(self.control_theta, self.control_points, bc_type="periodic")

    @cached_property
    def _borders(self) -> tuple[np.ndarray, np.ndarray]:
        theta = np.linspace(0, 2 * np.pi, BORDER_SAMPLES_PER_CURVE * (len(self.control_theta) - 1))
        mid = self.midline(theta)
        normal = _unit_normals(self.midline(theta, 1))
        return mid + normal * self.width / 2, mid - normal * self.width / 2

    @cached_property
    def inner(self) -> CubicSpline:
        """Inner border as a periodic spline of its own polar angle."""
        return _polar_spline(self._borders[0])

    @cached_property
    def outer(self) -> CubicSpline:
        """Outer border as a periodic spline of its own polar angle."""
        return _polar_spline(self._borders[1])

    @property
    def inner_border(self) -> np.ndarray:
        return _closed_polyline(self.inner)

    @property
    def outer_border(self) -> np.ndarray:
        return _closed_polyline(self.outer)

    @cached_property
    def raster_segments(self) -> tuple[np.ndarray, np.ndarray]:
        """Inner and outer border points at the map's rasterisation angles."""
        phi = np.arange(RASTER_ANGLES) * (2 * np.pi / RASTER_ANGLES)
        return _eval_polar(self.inner, phi), _eval_polar(self.outer, phi)

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
        for name in ("midline", "_borders", "inner", "outer", "raster_segments"):
            if name in self.__dict__:  # cached geometry does not depend on obstacles
                track.__dict__[name] = self.__dict__[name]
        return track

    def fits_grid(self) -> bool:
        """True when every outer border point lies inside the map."""
        cells = _cells(self.raster_segments[1])
        return bool(np.all((cells >= 0) & (cells < GRID)))

    def is_valid_position(self, x: float, y: float) -> bool:
        i, j = cell_of(x, y)
        return 0 <= i < GRID and 0 <= j < GRID and bool(self.grid[i, j] & lidar.VALID_BIT)

    # -- persistence ----------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Compact, JSON-safe form (floats round-trip exactly through json)."""
        return {
            "version": FORMAT_VERSION,
            "width": float(self.width),
            "control_theta": self.control_theta.tolist(),
            "control_points": self.control_points.tolist(),
            "obstacles": self.obstacles.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> Track:
        if data.get("version") != FORMAT_VERSION:
            raise ValueError(f"unsupported track format version {data.get('version')!r}; expected {FORMAT_VERSION}")
        obstacles = np.array(data["obstacles"], dtype=np.float64).reshape(-1, 2, 2)
        return cls(np.array(data["control_theta"]), np.array(data["control_points"]), data["width"], obstacles)

    def __reduce__(self):
        return (Track.from_dict, (self.to_dict(),))  # compact: the maps are re-derived

    def __eq__(self, other) -> bool:
        if not isinstance(other, Track):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash((self.control_points.tobytes(), self.obstacles.tobytes(), self.width))


def cell_of(x, y):
    """World coordinates -> grid cell (i, j); int() truncates toward zero."""
    return int(x * CELLS_PER_UNIT) + GRID // 2, int(y * CELLS_PER_UNIT) + GRID // 2


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
    if curves < 5:
        raise ValueError(f"curves must be at least 5, got {curves}")
    if not 0 < track_width <= MAX_TRACK_WIDTH:
        raise ValueError(f"track_width must be in (0, {MAX_TRACK_WIDTH}], got {track_width}")
    if n_obstacles < 0:
        raise ValueError(f"n_obstacles must be >= 0, got {n_obstacles}")
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
    theta = 2 * np.pi * np.linspace(0, 1, curves)
    radius = _smoothed_radii(rng.random(curves))
    points = _polar(theta, radius)
    if chicanes:
        theta, points = _add_chicane(rng, theta, radius, points)
    points[-1] = points[0]  # exact periodicity for the spline
    return theta, points


def _smoothed_radii(var: np.ndarray) -> np.ndarray:
    """SPEC smoothing, in index order and cyclic (each step sees the ones before it)."""
    n = len(var)
    for i in range(n):  # 20 scalars, sequentially dependent: not worth vectorising
        prev, nxt = var[i - 1], var[(i + 1) % n]
        s = 2 * var[i] - (prev + nxt)
        if s > 1:
            var[i] = (1 + prev + nxt) / 2
        elif s < -1:
            var[i] = (prev + nxt - 1) / 2
    var = 0.5 * var + 0.7
    var[-1] = var[0]
    return var


def _polar(theta, radius) -> np.ndarray:
    return np.stack([np.cos(theta) * radius, np.sin(theta) * radius], axis=-1)


def _add_chicane(rng, theta, radius, points):
    """Replace control point c by five points on the chord from c-1 to c+1, inner pair pushed apart."""
    c = int(rng.integers(1, len(theta) - 2))  # uniform in [1, curves - 3]
    delta = abs(theta[c - 1] - theta[c])
    offsets = np.array([-CHICANE_OUTER, -CHICANE_INNER, 0.0, CHICANE_INNER, CHICANE_OUTER]) * delta
    new_theta = np.concatenate([theta[:c], theta[c] + offsets, theta[c + 1:]])
    new_radius = np.concatenate([radius[:c], np.full(5, radius[c]), radius[c + 1:]])
    new_points = _polar(new_theta, new_radius)
    chicane = _on_chord(theta[c] + offsets, points[c - 1], points[c + 1])
    push = np.array([1 + CHICANE_PUSH, 1 - CHICANE_PUSH])
    if rng.random() >= 0.5:
        push = push[::-1]
    chicane[1] *= push[0]
    chicane[3] *= push[1]
    new_points[c:c + 5] = chicane
    return new_theta, new_points


def _on_chord(angles, a, b) -> np.ndarray:
    """Intersect the rays from the origin at `angles` with the line through a and b."""
    direction = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    chord = b - a
    # Solve t * direction = a + s * chord for t: t = cross(a, chord) / cross(direction, chord).
    t = (a[0] * chord[1] - a[1] * chord[0]) / (direction[:, 0] * chord[1] - direction[:, 1] * chord[0])
    return direction * t[:, None]


# -- borders -------------------------------------------------------------------------------
def _unit_normals(derivative: np.ndarray) -> np.ndarray:
    dx, dy = derivative[..., 0], derivative[..., 1]
    return np.stack([-dy, dx], axis=-1) / np.hypot(dx, dy)[..., None]


def _border_angles(points: np.ndarray) -> np.ndarray:
    return np.unwrap(np.arctan2(points[:, 1], points[:, 0]))


def _borders_are_star_shaped(track: Track) -> bool:
    """Each border must be a function of its polar angle (strictly increasing angles)."""
    return all(bool(np.all(np.diff(_border_angles(b)) > 0)) for b in track._borders)


def _polar_spline(points: np.ndarray) -> CubicSpline:
    phi = _border_angles(points)
    points = points.copy()
    points[-1] = points[0]
    return CubicSpline(phi, points, bc_type="periodic")


def _eval_polar(spline: CubicSpline, phi, nu: int = 0) -> np.ndarray:
    """Evaluate a border spline at polar angles in [0, 2*pi), whatever its starting angle."""
    start = spline.x[0]
    return spline(start + np.mod(np.asarray(phi) - start, 2 * np.pi), nu)


def _closed_polyline(spline: CubicSpline, samples: int = 720) -> np.ndarray:
    return _eval_polar(spline, np.linspace(0, 2 * np.pi, samples + 1))


def _cells(points: np.ndarray) -> np.ndarray:
    return np.trunc(points * CELLS_PER_UNIT).astype(np.int64) + GRID // 2


# -- obstacles -----------------------------------------------------------------------------
def _draw_obstacles(rng: np.random.Generator, track: Track, count: int) -> np.ndarray:
    """Obstacle segments along the track, offset inward from the outer border (SPEC 'Obstacles')."""
    slots = count + 2
    u = rng.uniform(2 * np.pi / (2 * slots), 2 * np.pi / slots, size=slots)
    phi = np.arange(slots) * (2 * np.pi / slots) + u
    phi = phi[1:count + 1]
    sides = rng.choice([0.85, 0.15], size=count) * track.width
    ends = []
    for angles in (phi, phi - OBSTACLE_LENGTH):
        border = _eval_polar(track.outer, angles)
        inward = _unit_normals(_eval_polar(track.outer, angles, 1))
        ends.append(border + inward * sides[:, None])
    return np.stack(ends, axis=1)


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array
