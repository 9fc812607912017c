# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""Compiled core of MicroRacer: grid rasterisation, the lidar and the batched car step.

Everything that runs per cell, per ray or per car lives here, so both environments
(Gymnasium and PettingZoo) advance all their cars with one call per step.

Grid convention (SPEC): world (x, y) -> cell (i, j) = (int(x*500) + 650, int(y*500) + 650),
`int` truncating toward zero, on a 1300 x 1300 row-major uint8 map indexed [i, j] whose bits
are the layers VALID, FREE and ROAD (one allocation per track).
"""
import numpy as np
cimport numpy as cnp
from libc.math cimport atan2, cos, sin, fmod, isnan, M_PI
from libc.string cimport memset

cnp.import_array()

cdef enum:
    GRID = 1300                  # cells per side
    ORIGIN = 650                 # cell of world coordinate 0
    N_RAYS = 19
    FINE_STEPS = 10              # lidar steps of 1/250 before switching to 1/100
    # Bits of a grid cell
    VALID = 1                    # a car may be here (road minus obstacles)
    FREE = 2                     # the lidar sees through it: the cell and its 4 neighbours are valid
    ROAD = 4                     # rasterised road, obstacles included
    # Outcome codes, in the order of league.physics.OUTCOMES
    RUNNING = 0
    FINISHED = 1
    OFF_ROAD = 2
    WRONG_DIRECTION = 3
    TOO_SLOW = 4
    RETIRED = 5                  # taken out of the race from outside (e.g. its agent failed)

cdef double CELLS_PER_UNIT = 500.0
cdef double FINE_STEP = 0.004     # 1/250
cdef double COARSE_STEP = 0.01    # 1/100
cdef double REFINE_STEP = 0.002   # 1/500: the reading's accuracy
cdef double TURN_LIMIT_COEFF = 1.741  # turn bound = min(max_turn, 1.741 * tstep / v)
cdef double CRASH_REWARD = -3.0
cdef double MIN_SPEED = 0.05      # low-speed termination threshold

N_LIDAR_RAYS = N_RAYS
GRID_SIZE = GRID
VALID_BIT, FREE_BIT, ROAD_BIT = VALID, FREE, ROAD


cdef inline int to_cell(double v) noexcept nogil:
    # C casts truncate toward zero, like Python's int().
    return <int>(v * CELLS_PER_UNIT) + ORIGIN


cdef inline bint cell_has(const unsigned char* grid, double x, double y, unsigned char bit) noexcept nogil:
    """True when the cell of world point (x, y) is on the grid and has the given bit."""
    cdef int i = to_cell(x)
    cdef int j = to_cell(y)
    if <unsigned int>i >= GRID or <unsigned int>j >= GRID:
        return False
    return (grid[i * GRID + j] & bit) != 0


# -- rasterisation ---------------------------------------------------------------------------
cdef inline int round_half_away(double v) noexcept nogil:
    return <int>(v + 0.5) if v >= 0 else <int>(v - 0.5)


cdef void paint(unsigned char* grid, int i, int j, int half, bint set_bits, unsigned char bits) noexcept nogil:
    """Set (or clear) bits on the (2*half+1)^2 square of cells around (i, j), clipped to the grid."""
    cdef int a, b
    cdef unsigned char keep = <unsigned char>(~bits)
    for a in range(max(i - half, 0), min(i + half + 1, GRID)):
        for b in range(max(j - half, 0), min(j + half + 1, GRID)):
            if set_bits:
                grid[a * GRID + b] |= bits
            else:
                grid[a * GRID + b] &= keep


cdef void paint_dda(unsigned char* grid, double x0, double y0, double x1, double y1,
                    int half, bint set_bits, unsigned char bits) noexcept nogil:
    """DDA line between the cells of two world points, a square brush at each step."""
    cdef int i0 = to_cell(x0), j0 = to_cell(y0), i1 = to_cell(x1), j1 = to_cell(y1)
    cdef int di = i1 - i0, dj = j1 - j0
    cdef int steps = max(abs(di), abs(dj))
    cdef int s
    if steps == 0:
        paint(grid, i0, j0, half, set_bits, bits)
        return
    for s in range(steps + 1):
        paint(grid, round_half_away(i0 + di * (<double>s / steps)), round_half_away(j0 + dj * (<double>s / steps)),
              half, set_bits, bits)


def rasterise_track(const double[:, ::1] inner, const double[:, ::1] outer,
                    const double[:, :, ::1] obstacles, int obstacle_half):
    """The track's grid: road from the segments inner[k] -> outer[k] (3x3 brush), obstacles
    (a (2*obstacle_half+1) square brush along each segment) cleared from VALID, and FREE."""
    grid = np.zeros((GRID, GRID), dtype=np.uint8)
    cdef unsigned char[:, ::1] view = grid
    cdef unsigned char* g = &view[0, 0]
    cdef Py_ssize_t k
    with nogil:
        for k in range(inner.shape[0]):
            paint_dda(g, inner[k, 0], inner[k, 1], outer[k, 0], outer[k, 1], 1, True, ROAD | VALID)
        for k in range(obstacles.shape[0]):
            paint_dda(g, obstacles[k, 0, 0], obstacles[k, 0, 1], obstacles[k, 1, 0], obstacles[k, 1, 1],
                      obstacle_half, False, VALID)
        mark_free(g)
    return grid


cdef void mark_free(unsigned char* g) noexcept nogil:
    """FREE where the cell and its 4 neighbours are VALID (the map's edge is never free)."""
    cdef Py_ssize_t i, j
    cdef unsigned char* row
    cdef unsigned char free_row[GRID]  # a separate buffer keeps the inner loop vectorisable
    free_row[0] = free_row[GRID - 1] = 0
    for i in range(1, GRID - 1):
        row = g + i * GRID
        for j in range(1, GRID - 1):
            # (cell & up & down & left & right & VALID) is 0 or 1; shift it onto the FREE bit.
            free_row[j] = (row[j] & row[j - GRID] & row[j + GRID] & row[j - 1] & row[j + 1] & VALID) << 1
        for j in range(GRID):
            row[j] |= free_row[j]


# -- lidar -----------------------------------------------------------------------------------
cdef double ray_length(const unsigned char* grid, double x, double y, double dx, double dy) noexcept nogil:
    """March along a unit direction: 10 steps of 1/250, then 1/100, then refine by 1/500.

    Returns the distance of the last free point: the first blocked point lies within 1/500 past it.
    """
    cdef int k
    cdef double d = 0.0, step = FINE_STEP, nd
    for k in range(1, FINE_STEPS + 1):
        nd = k * FINE_STEP
        if not cell_has(grid, x + nd * dx, y + nd * dy, FREE):
            break
        d = nd
    else:
        step = COARSE_STEP
        while True:
            nd = d + COARSE_STEP
            if not cell_has(grid, x + nd * dx, y + nd * dy, FREE):
                break
            d = nd
    # The point d + step is blocked: find the last free point before it, 1/500 at a time.
    for k in range(<int>(step / REFINE_STEP + 0.5) - 1):
        nd = d + REFINE_STEP
        if not cell_has(grid, x + nd * dx, y + nd * dy, FREE):
            break
        d = nd
    return d


# Ray offsets from the heading: 19 rays over [-30 deg, +30 deg], counter-clockwise.
cdef double RAY_COS[N_RAYS]
cdef double RAY_SIN[N_RAYS]
cdef int _m
for _m in range(N_RAYS):
    RAY_COS[_m] = cos(-M_PI / 6 + _m * (M_PI / 3) / (N_RAYS - 1))
    RAY_SIN[_m] = sin(-M_PI / 6 + _m * (M_PI / 3) / (N_RAYS - 1))


cdef void scan(const unsigned char* grid, double x, double y, double heading, double* out) noexcept nogil:
    cdef double ch = cos(heading), sh = sin(heading)
    cdef int m
    for m in range(N_RAYS):
        out[m] = ray_length(grid, x, y, ch * RAY_COS[m] - sh * RAY_SIN[m], sh * RAY_COS[m] + ch * RAY_SIN[m])


def lidar(const unsigned char[:, ::1] grid, double x, double y, double heading):
    """The 19 lidar readings of a car at (x, y) with the given heading, on a track grid."""
    out = np.empty(N_RAYS, dtype=np.float64)
    cdef double[::1] view = out
    scan(&grid[0, 0], x, y, heading, &view[0])
    return out


cdef void write_observation(const double* rays, double speed, bint compact, float* obs) noexcept nogil:
    """Compact: [direction, left, max, right, speed]; lidar: 19 readings + speed."""
    cdef int m, k = 0
    if not compact:
        for m in range(N_RAYS):
            obs[m] = <float>rays[m]
        obs[N_RAYS] = <float>speed
        return
    for m in range(1, N_RAYS):
        if rays[m] > rays[k]:
            k = m
    obs[0] = <float>(-M_PI / 6 + k * (M_PI / 3) / (N_RAYS - 1))
    obs[1] = <float>rays[k - 1 if k > 0 else k]
    obs[2] = <float>rays[k]
    obs[3] = <float>rays[k + 1 if k < N_RAYS - 1 else k]
    obs[4] = <float>speed


# -- cars ------------------------------------------------------------------------------------
OUTCOME_NAMES = ("running", "finished", "off_road", "wrong_direction", "too_slow", "retired")


cdef class CarBatch:
    """N cars on one track, advanced together (SPEC 'Car').

    Arrays are exposed read-only-by-convention to Python (positions for rendering and
    replays, outcomes, observations); all per-step bookkeeping happens here in C.
    """
    cdef readonly cnp.ndarray grid, x, y, heading, speed, theta, outcome, rays, obs, reward
    cdef readonly cnp.ndarray distance, finish_time, steps_taken
    cdef readonly double tstep, max_acc, max_turn
    cdef readonly bint turn_limit, low_speed_termination, compact
    cdef readonly int n, obs_dim
    cdef readonly long steps
    cdef const unsigned char* g
    cdef double* xs
    cdef double* ys
    cdef double* hs
    cdef double* vs
    cdef double* ts
    cdef double* ds
    cdef double* ft
    cdef double* rw
    cdef double* ry
    cdef long* taken
    cdef signed char* oc
    cdef float* ob

    def __init__(self, int n, cnp.ndarray grid, *, double tstep, double max_acc, double max_turn,
                 bint turn_limit, bint low_speed_termination, bint compact):
        if grid.dtype != np.uint8 or (<object>grid).shape != (GRID, GRID) or not grid.flags.c_contiguous:
            raise ValueError(f"grid must be a C-contiguous uint8 array of shape ({GRID}, {GRID})")
        self.n = n
        self.grid = grid
        self.tstep, self.max_acc, self.max_turn = tstep, max_acc, max_turn
        self.turn_limit, self.low_speed_termination, self.compact = turn_limit, low_speed_termination, compact
        self.obs_dim = 5 if compact else N_RAYS + 1
        self.x, self.y, self.heading, self.speed, self.theta = [np.zeros(n) for _ in range(5)]
        self.distance, self.finish_time, self.reward = np.zeros(n), np.full(n, np.nan), np.zeros(n)
        self.steps_taken = np.zeros(n, dtype=np.int_)
        self.outcome = np.zeros(n, dtype=np.int8)
        self.rays = np.zeros((n, N_RAYS))
        self.obs = np.zeros((n, self.obs_dim), dtype=np.float32)
        self.g = <const unsigned char*>cnp.PyArray_DATA(grid)
        self.xs, self.ys = <double*>cnp.PyArray_DATA(self.x), <double*>cnp.PyArray_DATA(self.y)
        self.hs, self.vs = <double*>cnp.PyArray_DATA(self.heading), <double*>cnp.PyArray_DATA(self.speed)
        self.ts, self.ds = <double*>cnp.PyArray_DATA(self.theta), <double*>cnp.PyArray_DATA(self.distance)
        self.ft, self.rw = <double*>cnp.PyArray_DATA(self.finish_time), <double*>cnp.PyArray_DATA(self.reward)
        self.ry, self.taken = <double*>cnp.PyArray_DATA(self.rays), <long*>cnp.PyArray_DATA(self.steps_taken)
        self.oc, self.ob = <signed char*>cnp.PyArray_DATA(self.outcome), <float*>cnp.PyArray_DATA(self.obs)

    def reset(self, double x, double y, double heading, double speed):
        """Put every car at the same start, with the same speed."""
        cdef int c
        self.steps = 0
        scan(self.g, x, y, heading, self.ry)
        for c in range(self.n):
            self.xs[c], self.ys[c], self.hs[c], self.vs[c], self.ts[c] = x, y, heading, speed, atan2(y, x)
            self.ds[c], self.ft[c], self.rw[c], self.taken[c], self.oc[c] = 0.0, np.nan, 0.0, 0, RUNNING
            if c > 0:
                self.rays[c, :] = self.rays[0, :]
            write_observation(self.ry + c * N_RAYS, speed, self.compact, self.ob + c * self.obs_dim)

    def step(self, const float[:, ::1] actions):
        """Advance every running car by one step; actions (n, 2) [acceleration, turn].

        Updates obs (a crashed car keeps its last valid observation), reward, outcome,
        distance, steps_taken and, for a car finishing in this step, finish_time
        interpolated inside the step. Returns the number of cars still running.
        """
        cdef int c, running = 0
        if actions.shape[0] != self.n or actions.shape[1] != 2:
            raise ValueError(f"actions must have shape ({self.n}, 2), got ({actions.shape[0]}, {actions.shape[1]})")
        for c in range(self.n):
            if self.oc[c] == RUNNING and (isnan(actions[c, 0]) or isnan(actions[c, 1])):
                raise ValueError(f"the action of car {c} contains NaN; actions must be finite numbers in [-1, 1]")
        self.steps += 1
        with nogil:
            for c in range(self.n):
                self.rw[c] = 0.0
                if self.oc[c] == RUNNING:
                    self.move(c, actions[c, 0], actions[c, 1])
                    running += self.oc[c] == RUNNING
        return running

    def step_one(self, double acc, double turn):
        """`step` for a batch of one car, without building an array; returns its outcome code."""
        if isnan(acc) or isnan(turn):
            raise ValueError("the action contains NaN; actions must be finite numbers in [-1, 1]")
        self.steps += 1
        self.rw[0] = 0.0
        if self.oc[0] == RUNNING:
            self.move(0, acc, turn)
        return self.oc[0]

    cdef void move(self, int c, double acc, double turn) noexcept nogil:
        cdef double v, bound, h, nx, ny, nt, unwrapped, th = self.ts[c]
        acc = min(1.0, max(-1.0, acc))
        turn = min(1.0, max(-1.0, turn))
        v = max(0.0, self.vs[c] + acc * self.max_acc * self.tstep)
        bound = self.max_turn
        if self.turn_limit and v > 0:
            bound = min(self.max_turn, TURN_LIMIT_COEFF * self.tstep / v)
        h = self.hs[c] - turn * bound
        nx = self.xs[c] + v * cos(h) * self.tstep
        ny = self.ys[c] + v * sin(h) * self.tstep
        nt = atan2(ny, nx)
        unwrapped = nt - 2 * M_PI if (th < -0.9 * M_PI and nt > 0.9 * M_PI) else nt
        self.taken[c] += 1
        # The checks, in SPEC's order; a failed check leaves the car where it was.
        if not cell_has(self.g, nx, ny, VALID):
            self.oc[c] = OFF_ROAD
        elif not unwrapped < th:
            self.oc[c] = WRONG_DIRECTION
        elif self.low_speed_termination and v < MIN_SPEED:
            self.oc[c] = TOO_SLOW
        if self.oc[c] != RUNNING:
            self.rw[c] = CRASH_REWARD
            return
        self.rw[c] = v * self.tstep
        self.ds[c] += self.rw[c]
        if th > 0 and nt <= 0:
            self.oc[c] = FINISHED
            # linear in the polar angle: the line theta = 0 is crossed at fraction th / (th - nt)
            self.ft[c] = (self.steps - 1 + th / (th - nt)) * self.tstep
        self.xs[c], self.ys[c], self.hs[c], self.vs[c], self.ts[c] = nx, ny, h, v, nt
        scan(self.g, nx, ny, h, self.ry + c * N_RAYS)
        write_observation(self.ry + c * N_RAYS, v, self.compact, self.ob + c * self.obs_dim)

    def __reduce__(self):
        options = dict(tstep=self.tstep, max_acc=self.max_acc, max_turn=self.max_turn, turn_limit=self.turn_limit,
                       low_speed_termination=self.low_speed_termination, compact=self.compact)
        state = {name: getattr(self, name).copy() for name in STATE_ARRAYS}
        state["steps"] = self.steps
        return (_restore_car_batch, (self.n, self.grid, options, state))

    def _set_state(self, dict state):
        for name in STATE_ARRAYS:
            np.copyto(getattr(self, name), state[name])
        self.steps = state["steps"]

    def retire(self, int c):
        """Take car c out of the race where it stands; it is done, with outcome "retired"."""
        if self.oc[c] == RUNNING:
            self.oc[c] = RETIRED

    def observation(self, int c):
        """A copy of car c's observation."""
        return self.obs[c].copy()

    def progress(self, int c):
        """Fraction of the lap covered, from the polar angle (the race runs clockwise from 0)."""
        if self.oc[c] == FINISHED:
            return 1.0
        cdef double p = fmod(-self.ts[c], 2 * M_PI)
        return (p + 2 * M_PI if p < 0 else p) / (2 * M_PI)

    def info(self, int c):
        """Car c's outcome, lap progress, time (s), distance and speed."""
        return {
            "outcome": OUTCOME_NAMES[self.oc[c]],
            "progress": self.progress(c),
            "time": self.taken[c] * self.tstep,
            "distance": self.ds[c],
            "speed": self.vs[c],
        }


STATE_ARRAYS = ("x", "y", "heading", "speed", "theta", "outcome", "rays", "obs", "reward",
                "distance", "finish_time", "steps_taken")


def _restore_car_batch(n, grid, options, state):
    """Unpickle a CarBatch (its state arrays are copied in)."""
    cars = CarBatch(n, np.ascontiguousarray(grid), **options)
    cars._set_state(state)
    return cars
