"""Slow, obviously-correct pure-Python references, kept only for tests."""
import math

GRID = 1300


def cell(v: float) -> int:
    return int(v * 500) + 650


def is_free(valid, x: float, y: float) -> bool:
    """SPEC: a point is free when its cell and the 4 cells next to it are all valid."""
    i, j = cell(x), cell(y)
    for a, b in ((i, j), (i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)):
        if not (0 <= a < GRID and 0 <= b < GRID and valid[a, b]):
            return False
    return True


def ray(valid, x, y, angle):
    """SPEC's march: 10 steps of 1/250, then 1/100; step back; refine by 1/500."""
    dx, dy = math.cos(angle), math.sin(angle)
    d, step = 0.0, 0.004
    for k in range(1, 11):
        if not is_free(valid, x + k * 0.004 * dx, y + k * 0.004 * dy):
            break
        d = k * 0.004
    else:
        step = 0.01
        while is_free(valid, x + (d + 0.01) * dx, y + (d + 0.01) * dy):
            d += 0.01
    for _ in range(round(step / 0.002) - 1):
        if not is_free(valid, x + (d + 0.002) * dx, y + (d + 0.002) * dy):
            break
        d += 0.002
    return d


def fine_ray(valid, x, y, angle, step=1 / 5000):
    """The ideal reading: march in tiny steps to the first blocked point past the car's own cell."""
    dx, dy = math.cos(angle), math.sin(angle)
    own = (cell(x), cell(y))
    k = 1
    while ((cell(x + k * step * dx), cell(y + k * step * dy)) == own
           or is_free(valid, x + k * step * dx, y + k * step * dy)):
        k += 1
    return (k - 1) * step


def lidar(valid, x, y, heading):
    return [ray(valid, x, y, heading - math.pi / 6 + m * (math.pi / 3) / 18) for m in range(19)]


def compact(readings, speed):
    k = max(range(19), key=lambda m: (readings[m], -m))  # first maximum
    return [
        -math.pi / 6 + k * (math.pi / 3) / 18,
        readings[k - 1] if k > 0 else readings[k],
        readings[k],
        readings[k + 1] if k < 18 else readings[k],
        speed,
    ]


def heuristic(obs):
    """SPEC's driver on a compact observation."""
    direction, speed = float(obs[0]), float(obs[4])
    return [0.5 if speed < 0.25 else -0.2, max(-1.0, min(1.0, -direction / (math.pi / 6)))]


# -- tracks: SPEC "Track" with scipy's splines and a numpy rasterisation ----------------------
# The simulator builds the same splines in its compiled core and rasterises in C; these are
# the plain versions (the generator as it was before, scipy.interpolate.CubicSpline), for the
# bit-for-bit comparison in tests/test_track.py.

import numpy as np  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402


def track_dict(rng, curves=20, track_width=0.04, chicanes=True, obstacles=True, n_obstacles=6):
    """`generate_track(rng, ...).to_dict()`, derived with scipy; returns (dict, inner, outer)."""
    for _ in range(100):
        theta = 2 * np.pi * np.linspace(0, 1, curves)
        radius = _smoothed_radii(rng.random(curves))
        points = _polar(theta, radius)
        if chicanes:
            theta, points = _add_chicane(rng, theta, radius, points)
        points[-1] = points[0]
        midline = CubicSpline(theta, points, bc_type="periodic")
        borders = _borders(midline, theta, track_width)
        if not all(np.all(np.diff(_angles(b)) > 0) for b in borders):
            continue
        inner, outer = (_polar_spline(b) for b in borders)
        if np.all((_cells(_eval_polar(outer, RASTER_PHI)) >= 0) & (_cells(_eval_polar(outer, RASTER_PHI)) < GRID)):
            break
    else:
        raise RuntimeError("no track fitted the grid in 100 draws")
    segments = np.zeros((0, 2, 2))
    if obstacles and n_obstacles:
        segments = _obstacles(rng, outer, track_width, n_obstacles)
    data = {"version": 1, "width": float(track_width), "control_theta": theta.tolist(),
            "control_points": points.tolist(), "obstacles": segments.tolist()}
    return data, inner, outer


RASTER_PHI = np.arange(2000) * (2 * np.pi / 2000)


def _smoothed_radii(var):
    n = len(var)
    for i in range(n):
        prev, nxt = var[i - 1], var[(i + 1) % n]
        s = 2 * var[i] - (prev + nxt)
        if s > 1:
            var[i] = (1 + prev + nxt) / 2
        elif s < -1:
            var[i] = (prev + nxt - 1) / 2
    var = 0.5 * var + 0.7
    var[-1] = var[0]
    return var


def _polar(theta, radius):
    return np.stack([np.cos(theta) * radius, np.sin(theta) * radius], axis=-1)


def _add_chicane(rng, theta, radius, points):
    c = int(rng.integers(1, len(theta) - 2))
    delta = abs(theta[c - 1] - theta[c])
    offsets = np.array([-1 / 3, -1 / 25, 0.0, 1 / 25, 1 / 3]) * delta
    new_theta = np.concatenate([theta[:c], theta[c] + offsets, theta[c + 1:]])
    new_points = _polar(new_theta, np.concatenate([radius[:c], np.full(5, radius[c]), radius[c + 1:]]))
    angles = theta[c] + offsets
    direction = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    a, chord = points[c - 1], points[c + 1] - points[c - 1]
    t = (a[0] * chord[1] - a[1] * chord[0]) / (direction[:, 0] * chord[1] - direction[:, 1] * chord[0])
    chicane = direction * t[:, None]
    push = np.array([1.02, 0.98])
    if rng.random() >= 0.5:
        push = push[::-1]
    chicane[1] *= push[0]
    chicane[3] *= push[1]
    new_points[c:c + 5] = chicane
    return new_theta, new_points


def _normals(derivative):
    dx, dy = derivative[..., 0], derivative[..., 1]
    return np.stack([-dy, dx], axis=-1) / np.hypot(dx, dy)[..., None]


def _borders(midline, theta, width):
    samples = np.linspace(0, 2 * np.pi, 6 * (len(theta) - 1))
    mid, normal = midline(samples), _normals(midline(samples, 1))
    return mid + normal * width / 2, mid - normal * width / 2


def _angles(points):
    return np.unwrap(np.arctan2(points[:, 1], points[:, 0]))


def _polar_spline(points):
    points = points.copy()
    phi = _angles(points)
    points[-1] = points[0]
    return CubicSpline(phi, points, bc_type="periodic")


def _eval_polar(spline, phi, nu=0):
    start = spline.x[0]
    return spline(start + np.mod(np.asarray(phi) - start, 2 * np.pi), nu)


def _cells(points):
    return np.trunc(points * 500).astype(np.int64) + 650


def _obstacles(rng, outer, width, count):
    slots = count + 2
    u = rng.uniform(2 * np.pi / (2 * slots), 2 * np.pi / slots, size=slots)
    phi = (np.arange(slots) * (2 * np.pi / slots) + u)[1:count + 1]
    sides = rng.choice([0.85, 0.15], size=count) * width
    ends = [_eval_polar(outer, a) + _normals(_eval_polar(outer, a, 1)) * sides[:, None]
            for a in (phi, phi - np.pi / 150)]
    return np.stack(ends, axis=1)


def grid(inner, outer, obstacles, width):
    """SPEC's map (VALID = 1, FREE = 2, ROAD = 4), painted with numpy fancy indexing."""
    valid, road = np.zeros((GRID, GRID), bool), np.zeros((GRID, GRID), bool)
    for _mask, a, b, half, value in ((road, _eval_polar(inner, RASTER_PHI), _eval_polar(outer, RASTER_PHI), 1, True),
                                    (valid, obstacles[:, 0], obstacles[:, 1], int(width * 500 / 4), False)):
        if value:
            _paint(road, a, b, half)
            valid |= road
        elif len(a):
            blocked = np.zeros_like(valid)
            _paint(blocked, a, b, half)
            valid &= ~blocked
    free = np.zeros_like(valid)
    free[1:-1, 1:-1] = valid[1:-1, 1:-1] & valid[:-2, 1:-1] & valid[2:, 1:-1] & valid[1:-1, :-2] & valid[1:-1, 2:]
    return (valid * 1 + free * 2 + road * 4).astype(np.uint8)


def _paint(mask, starts, ends, half):
    """A DDA line between the cells of each start and end point, a square brush at every step."""
    i0, j0 = _cells(starts).T
    i1, j1 = _cells(ends).T
    steps = np.maximum(np.abs(i1 - i0), np.abs(j1 - j0))
    segment = np.repeat(np.arange(len(steps)), steps + 1)
    s = np.arange(len(segment)) - np.repeat(np.cumsum(steps + 1) - (steps + 1), steps + 1)
    fraction = s / np.maximum(steps[segment], 1)
    rows = _round_half_away(i0[segment] + (i1 - i0)[segment] * fraction)
    cols = _round_half_away(j0[segment] + (j1 - j0)[segment] * fraction)
    for di in range(-half, half + 1):
        for dj in range(-half, half + 1):
            r, c = rows + di, cols + dj
            inside = (r >= 0) & (r < GRID) & (c >= 0) & (c < GRID)
            mask[r[inside], c[inside]] = True


def _round_half_away(v):
    return np.where(v >= 0, np.trunc(v + 0.5), np.trunc(v - 0.5)).astype(np.int64)


# -- the thesis' Racer (tracks.py of github.com/asperti/MicroRacer) ------------------------
# Its attributes are plain ones, all writable. __init__ sets these (reset reads the track's,
# step the physics'), reset sets the next ones and step sets max_turnrad.
THESIS_INIT_ATTRIBUTES = {"curves": 20, "tstep": 0.04, "max_acc": 0.1, "max_turn": math.pi / 6, "track_width": 0.04,
                          "obstacles_number": 6, "obstacles": True, "chicanes": True, "turn_limit": True,
                          "low_speed_termination": True}
THESIS_RESET_ATTRIBUTES = ("cs", "csin", "csout", "map", "obs_pos", "cartheta", "carx", "cary", "carvx", "carvy",
                           "done", "completation", "sinit_v")
THESIS_STEP_ATTRIBUTES = ("max_turnrad",)


def thesis_obs_pos(ends):
    """The original's obs_pos of obstacles given as (k, 2 ends, xy), the end at the obstacle's
    angle first: its `np.stack([x_1, x_2, y_1, y_2], axis=1)`; `[]` without obstacles."""
    if not len(ends):
        return []
    (x_1, y_1), (x_2, y_2) = ends[:, 0].T, ends[:, 1].T
    return np.stack([x_1, x_2, y_1, y_2], axis=1)
