"""Slow, obviously-correct pure-Python references, kept only for tests."""
import math

GRID = 1300


def cell(v: float) -> int:
    return int(v * 500) + 650


def is_valid(valid, x: float, y: float) -> bool:
    i, j = cell(x), cell(y)
    return 0 <= i < GRID and 0 <= j < GRID and bool(valid[i, j])


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
    while (cell(x + k * step * dx), cell(y + k * step * dy)) == own or is_free(valid, x + k * step * dx, y + k * step * dy):
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
