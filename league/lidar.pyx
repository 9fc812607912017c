# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The simulator's compiled core: track splines and rasterisation, the lidar and the batched car step.

Everything that runs per cell, per ray, per spline point or per car lives here, so the
environments advance all their cars with one call per step and a new track costs well under
a millisecond. Its numbers (GRID, N_RAYS, TSTEP, ...) are compiled in from league/constants.py
(setup.py passes them as Cython's compile_time_env).

Grid convention (SPEC): world (x, y) -> cell (i, j) = (int(x*500) + 650, int(y*500) + 650),
`int` truncating toward zero, on a GRID x GRID row-major uint8 map indexed [i, j] whose bits
are the layers VALID, FREE and ROAD (one allocation per track).
"""
import numpy as np
cimport numpy as cnp
from libc.math cimport atan2, cos, sin, fabs, fmod, copysign, hypot, isnan, M_PI, NAN
from libc.stdlib cimport malloc, free
from libc.string cimport memcpy, memset
from cpython.ref cimport PyObject, Py_INCREF, Py_XDECREF

from league.constants import OUTCOMES

cnp.import_array()

cdef extern from "numpy/arrayobject.h":
    object PyArray_Scalar(void* data, cnp.dtype descr, object base)

cdef cnp.dtype FLOAT64 = np.dtype(np.float64)


cdef inline object float64(double value):
    """`numpy.float64(value)` without a Python call (infos are numpy scalars)."""
    return PyArray_Scalar(&value, FLOAT64, None)


OUTCOME_CODES = tuple(np.int64(code) for code in range(len(OUTCOMES)))  # info["outcome_code"]

cdef enum:
    # Bits of a grid cell
    VALID = 1                    # a car may be here (road minus obstacles)
    FREE = 2                     # the lidar sees through it: the cell and its 4 neighbours are valid
    ROAD = 4                     # rasterised road, obstacles included

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


# -- periodic cubic splines ------------------------------------------------------------------
# The mid-line and the borders are periodic cubic splines, defined (SPEC "Track") as
# scipy.interpolate.CubicSpline(x, y, bc_type="periodic"). These functions do scipy's
# floating-point operations in scipy's order -- the derivative system condensed to a
# tridiagonal one and solved as LAPACK's gtsv does, then the power-basis evaluation of
# PPoly -- so every track stays bit for bit what scipy gives, without scipy's ~100 us of
# Python per spline. tests/test_track.py compares both on many tracks.

cdef void solve_tridiagonal(Py_ssize_t n, Py_ssize_t nrhs, double* dl, double* d, double* du,
                            double* b) noexcept nogil:
    """LAPACK's dgtsv: Gaussian elimination with partial pivoting, b (n, nrhs) row-major.

    Overwrites dl (with the second superdiagonal of U), d, du and b (with the solution).
    The matrices it gets here are diagonally dominant: no pivot is ever zero.
    """
    cdef Py_ssize_t i, j
    cdef double fact, temp
    for i in range(n - 1):
        if fabs(d[i]) >= fabs(dl[i]):  # no row interchange
            fact = dl[i] / d[i]
            d[i + 1] = d[i + 1] - fact * du[i]
            for j in range(nrhs):
                b[(i + 1) * nrhs + j] = b[(i + 1) * nrhs + j] - fact * b[i * nrhs + j]
            dl[i] = 0.0
        else:  # interchange rows i and i + 1
            fact = d[i] / dl[i]
            d[i] = dl[i]
            temp = d[i + 1]
            d[i + 1] = du[i] - fact * temp
            if i < n - 2:
                dl[i] = du[i + 1]
                du[i + 1] = -fact * dl[i]
            du[i] = temp
            for j in range(nrhs):
                temp = b[i * nrhs + j]
                b[i * nrhs + j] = b[(i + 1) * nrhs + j]
                b[(i + 1) * nrhs + j] = temp - fact * b[(i + 1) * nrhs + j]
    for j in range(nrhs):
        b[(n - 1) * nrhs + j] = b[(n - 1) * nrhs + j] / d[n - 1]
        if n > 1:
            b[(n - 2) * nrhs + j] = (b[(n - 2) * nrhs + j] - du[n - 2] * b[(n - 1) * nrhs + j]) / d[n - 2]
        for i in range(n - 3, -1, -1):
            b[i * nrhs + j] = (b[i * nrhs + j] - du[i] * b[(i + 1) * nrhs + j]
                               - dl[i] * b[(i + 2) * nrhs + j]) / d[i]


def periodic_spline(const double[::1] x, const double[:, ::1] y):
    """Coefficients c (4, n-1, dim), highest power first, of the periodic cubic spline through
    (x[k], y[k]): x strictly increasing, y[-1] == y[0], n >= 4 points of dim coordinates."""
    cdef Py_ssize_t n = x.shape[0], dim = y.shape[1], m = n - 2, i, j, r
    if n < 4 or y.shape[0] != n:
        raise ValueError(f"a periodic spline needs n >= 4 points and n values, got {n} and {y.shape[0]}")
    c_array = np.empty((4, n - 1, dim))
    cdef double* c = <double*>cnp.PyArray_DATA(c_array)
    cdef Py_ssize_t cs = (n - 1) * dim  # c[p, i, j] is c[p * cs + i * dim + j]
    # One scratch block (a track's splines are small): dx (n-1), slope (n-1, dim), s (n, dim),
    # the tridiagonal matrix once per solve (2, 3, m; gtsv overwrites it), the right-hand sides (2, m, dim).
    cdef double* dx = <double*>malloc(((n - 1) + (n - 1) * dim + n * dim + 6 * m + 2 * m * dim) * sizeof(double))
    if dx == NULL:
        raise MemoryError()
    cdef double* slope = dx + (n - 1)
    cdef double* s = slope + (n - 1) * dim
    cdef double* a = s + n * dim  # a[r, row, i] is a[(r * 3 + row) * m + i]
    cdef double* b = a + 6 * m  # b[r, i, j] is b[(r * m + i) * dim + j]
    cdef double s_last, t
    for i in range(n - 1):
        dx[i] = x[i + 1] - x[i]
        if not dx[i] > 0:
            free(dx)
            raise ValueError("the spline's x must be a strictly increasing sequence")
        for j in range(dim):
            slope[i * dim + j] = (y[i + 1, j] - y[i, j]) / dx[i]
    with nogil:
        memset(b, 0, 2 * m * dim * sizeof(double))
        # The (n-1)-unknown periodic system, condensed to (n-2) unknowns and solved for two
        # right-hand sides: b1 (row 0 of rhs) and b2 = -(the removed column) (row 1).
        for i in range(m):
            for r in range(2):
                a[(r * 3 + 1) * m + i] = 2 * (dx[n - 2] + dx[0]) if i == 0 else 2 * (dx[i - 1] + dx[i])  # diagonal
                a[(r * 3 + 0) * m + i] = (dx[n - 2] if i == 0 else dx[i - 1]) if i < m - 1 else 0.0  # du[i]
                a[(r * 3 + 2) * m + i] = dx[i + 1] if i < m - 1 else 0.0  # dl[i] = A[i+1, i]
            for j in range(dim):
                if i == 0:
                    b[i * dim + j] = 3 * (dx[0] * slope[(n - 2) * dim + j] + dx[n - 2] * slope[j])
                else:
                    b[i * dim + j] = 3 * (dx[i] * slope[(i - 1) * dim + j] + dx[i - 1] * slope[i * dim + j])
        for j in range(dim):
            b[(m + 0) * dim + j] = -dx[0]
            b[(m + m - 1) * dim + j] = -dx[n - 4]
        for r in range(2):
            solve_tridiagonal(m, dim, &a[(r * 3 + 2) * m], &a[(r * 3 + 1) * m], &a[r * 3 * m], &b[r * m * dim])
        for j in range(dim):
            s_last = ((3 * (dx[n - 2] * slope[(n - 3) * dim + j] + dx[n - 3] * slope[(n - 2) * dim + j])
                       - dx[n - 3] * b[j] - dx[n - 2] * b[(m - 1) * dim + j])
                      / (2 * (dx[n - 2] + dx[n - 3]) + dx[n - 3] * b[m * dim + j]
                         + dx[n - 2] * b[(m + m - 1) * dim + j]))
            for i in range(m):
                s[i * dim + j] = b[i * dim + j] + s_last * b[(m + i) * dim + j]
            s[(n - 2) * dim + j] = s_last
            s[(n - 1) * dim + j] = s[j]
        # Hermite form (scipy's CubicHermiteSpline) -> power basis on each interval.
        for i in range(n - 1):
            for j in range(dim):
                t = (s[i * dim + j] + s[(i + 1) * dim + j] - 2 * slope[i * dim + j]) / dx[i]
                c[i * dim + j] = t / dx[i]
                c[cs + i * dim + j] = (slope[i * dim + j] - s[i * dim + j]) / dx[i] - t
                c[2 * cs + i * dim + j] = s[i * dim + j]
                c[3 * cs + i * dim + j] = y[i, j]
    free(dx)
    return c_array


cdef inline double remainder(double a, double b) noexcept nogil:
    """numpy's float `a % b`: fmod, moved into b's sign."""
    cdef double mod = a if fabs(a) < fabs(b) else fmod(a, b)  # fmod(a, b) is exactly a then
    if mod != 0:
        if (b < 0) != (mod < 0):
            mod += b
    else:
        mod = copysign(0.0, b)
    return mod


cdef inline double cubic(double s, const double* c, Py_ssize_t stride, int nu) noexcept nogil:
    """scipy's evaluate_poly1: the nu-th derivative at offset s of the cubic whose coefficients,
    highest power first, are c[0], c[stride], c[2 * stride], c[3 * stride]."""
    cdef int kp, k
    cdef double res = 0.0, z = 1.0, prefactor
    if nu == 0:  # scipy's loop, unrolled: its products by z = 1 and by prefactor = 1 are exact
        res = res + c[3 * stride]
        res = res + c[2 * stride] * s
        z = s * s
        res = res + c[stride] * z
        z = z * s
        return res + c[0] * z
    if nu == 1:
        res = res + c[2 * stride]
        res = res + c[stride] * s * 2.0
        z = s * s
        return res + c[0] * z * 3.0
    for kp in range(nu, 4):
        prefactor = 1.0
        for k in range(kp, kp - nu, -1):
            prefactor *= k
        res = res + c[(3 - kp) * stride] * z * prefactor
        if kp < 3:
            z *= s
    return res


cdef Py_ssize_t evaluate_one(const double[::1] x, const double[:, :, ::1] c, double t, int nu, Py_ssize_t hint,
                             double* out) noexcept nogil:
    """Evaluate at t, mapped into [x[0], x[-1]] periodically (scipy's extrapolate="periodic");
    returns the interval used, the next call's first guess (sorted t: no search)."""
    cdef Py_ssize_t n = x.shape[0], low = 0, high = n - 2, mid, j
    t = x[0] + remainder(t - x[0], x[n - 1] - x[0])
    if not (x[0] <= t <= x[n - 1]):
        for j in range(c.shape[2]):
            out[j] = NAN
        return hint
    if t == x[n - 1]:
        low = n - 2
    elif x[hint] <= t < x[hint + 1]:
        low = hint
    else:
        while low < high:  # the interval with x[low] <= t < x[low + 1]
            mid = (low + high + 1) // 2
            if t < x[mid]:
                high = mid - 1
            else:
                low = mid
    for j in range(c.shape[2]):
        out[j] = cubic(t - x[low], &c[0, low, j], c.shape[1] * c.shape[2], nu)
    return low


def evaluate_spline(const double[::1] x, const double[:, :, ::1] c, t, int nu=0, bint polar=False):
    """Values (or nu-th derivatives, nu <= 3) of a periodic spline at t: shape t.shape + (dim,).

    polar: t are polar angles and x the spline's own polar angles, starting anywhere: each t is
    first taken modulo 2*pi from x[0] (numpy's `x[0] + np.mod(t - x[0], 2 * np.pi)`).
    """
    if not 0 <= nu <= 3:
        raise ValueError(f"derivative order nu must be 0, 1, 2 or 3, got {nu}")
    points = np.asarray(t, dtype=np.float64)
    flat = np.ascontiguousarray(points.ravel())
    out = np.empty((flat.shape[0], c.shape[2]))
    cdef const double[::1] ts = flat
    cdef double[:, ::1] view = out
    cdef Py_ssize_t k, interval = 0
    cdef double tk
    with nogil:
        for k in range(ts.shape[0]):
            tk = x[0] + remainder(ts[k] - x[0], 2 * M_PI) if polar else ts[k]
            interval = evaluate_one(x, c, tk, nu, interval, &view[k, 0])
    return out.reshape(points.shape + (c.shape[2],))


def offset_points(const double[::1] x, const double[:, :, ::1] c, const double[::1] t,
                  const double[:, ::1] offsets, bint polar=False):
    """Points at distances `offsets` along the unit normal (-y', x') of a 2-D periodic spline:
    out[m, k] = spline(t[k]) + normal(t[k]) * offsets[k or 0, m], shape (offsets' columns, len(t), 2).

    numpy's operations in numpy's order (the normal is (-dy, dx) / hypot(dx, dy), numpy's hypot
    being the C library's), so borders and obstacles are those the numpy code gave, bit for bit.
    polar: as evaluate_spline's."""
    cdef Py_ssize_t n = t.shape[0], width = offsets.shape[1], k, m, row_step = 1 if offsets.shape[0] > 1 else 0
    if c.shape[2] != 2 or offsets.shape[0] not in (1, n):
        raise ValueError("offset_points needs a 2-D spline and one row of offsets or one per point")
    out = np.empty((width, n, 2))
    cdef double[:, :, ::1] view = out
    cdef double point[2]
    cdef double slope[2]
    cdef double tk, h, nx, ny
    cdef Py_ssize_t interval = 0
    with nogil:
        for k in range(n):
            tk = x[0] + remainder(t[k] - x[0], 2 * M_PI) if polar else t[k]
            evaluate_one(x, c, tk, 0, interval, point)
            interval = evaluate_one(x, c, tk, 1, interval, slope)
            h = hypot(slope[0], slope[1])
            nx, ny = -slope[1] / h, slope[0] / h
            for m in range(width):
                view[m, k, 0] = point[0] + nx * offsets[k * row_step, m]
                view[m, k, 1] = point[1] + ny * offsets[k * row_step, m]
    return out


def strictly_increasing(const double[::1] values):
    """numpy's bool(np.all(values[1:] > values[:-1]))."""
    cdef Py_ssize_t k
    for k in range(1, values.shape[0]):
        if not values[k] > values[k - 1]:
            return False
    return True


def unwrap(const double[::1] angles):
    """numpy.unwrap(angles) with its defaults (period 2*pi), the same operations in the same order:
    every jump of more than pi between neighbours is taken back by a multiple of 2*pi."""
    cdef Py_ssize_t n = angles.shape[0], i
    out = np.empty(n)
    cdef double[::1] up = out
    cdef double dd, ddmod, correction, total = 0.0
    if n == 0:
        return out
    up[0] = angles[0]
    for i in range(1, n):
        dd = angles[i] - angles[i - 1]
        ddmod = remainder(dd + M_PI, 2 * M_PI) - M_PI
        if ddmod == -M_PI and dd > 0:
            ddmod = M_PI
        correction = 0.0 if fabs(dd) < M_PI else ddmod - dd
        total = correction if i == 1 else total + correction  # numpy's cumsum
        up[i] = angles[i] + total
    return out


def inside_grid(const double[:, ::1] points):
    """True when the cell of every world point (x, y) lies on the grid."""
    cdef Py_ssize_t k
    for k in range(points.shape[0]):
        if <unsigned int>to_cell(points[k, 0]) >= GRID or <unsigned int>to_cell(points[k, 1]) >= GRID:
            return False
    return True


# -- rasterisation ---------------------------------------------------------------------------
# The road is SPEC's DDA line from each inner border point to its outer point, drawn with a
# 3x3 brush, minus the obstacles' squares; FREE follows from VALID. Painting 9 cells per step
# and then sweeping the whole map cost most of a reset, so: each road step marks only its cell
# (CENTRE) and each obstacle step its square (BLOCKED), both marking the tiles they may reach;
# then one row-major sweep over the marked tiles sets ROAD where a CENTRE lies within one cell,
# VALID where ROAD is not BLOCKED, and FREE on the row above, clearing the scratch bits. The
# same cells as painting brush by brush (tests/test_track.py), in a fraction of the time.

cdef enum:
    CENTRE = 128                 # scratch bit: a road step lands on this cell
    BLOCKED = 64                 # scratch bit: an obstacle covers this cell
    TILE = 16                    # cells per side of a tile
    TILES = (GRID + TILE - 1) // TILE


cdef inline int round_half_away(double v) noexcept nogil:
    return <int>(v + 0.5) if v >= 0 else <int>(v - 0.5)


cdef inline int tile_of(int cell) noexcept nogil:
    return min(max(cell, 0), GRID - 1) // TILE


cdef void mark_tiles(unsigned char* tiles, int i0, int i1, int j0, int j1) noexcept nogil:
    """Mark the tiles of the cells [i0, i1] x [j0, j1] (clipped to the grid)."""
    cdef int a, b
    for a in range(tile_of(i0), tile_of(i1) + 1):
        for b in range(tile_of(j0), tile_of(j1) + 1):
            tiles[a * TILES + b] = 1


cdef inline void line_cell(int i0, int j0, int di, int dj, int steps, int s, int* i, int* j) noexcept nogil:
    """Step s of SPEC's DDA line: (round(i0 + di * s/steps), round(j0 + dj * s/steps)), halves
    away from zero; along the longer axis that is exactly i0 +- s."""
    if abs(di) == steps:
        i[0] = i0 + (s if di > 0 else -s)
        j[0] = round_half_away(j0 + dj * (<double>s / steps))
    else:
        i[0] = round_half_away(i0 + di * (<double>s / steps))
        j[0] = j0 + (s if dj > 0 else -s)


cdef void trace_road(unsigned char* grid, double x0, double y0, double x1, double y1, unsigned char* tiles) noexcept nogil:
    """The DDA line of a road segment: each step's cell is marked CENTRE (its 3x3 brush is
    painted by the sweep), and the tiles the brush may reach are marked."""
    cdef int i0 = to_cell(x0), j0 = to_cell(y0), i1 = to_cell(x1), j1 = to_cell(y1)
    cdef int steps = max(abs(i1 - i0), abs(j1 - j0)), s, i = i0, j = j0
    mark_tiles(tiles, min(i0, i1) - 1, max(i0, i1) + 1, min(j0, j1) - 1, max(j0, j1) + 1)
    for s in range(steps + 1):
        if steps:
            line_cell(i0, j0, i1 - i0, j1 - j0, steps, s, &i, &j)
        if <unsigned int>i < GRID and <unsigned int>j < GRID:
            grid[i * GRID + j] |= CENTRE


cdef void trace_obstacle(unsigned char* grid, double x0, double y0, double x1, double y1, int half,
                         unsigned char* tiles) noexcept nogil:
    """The DDA line of an obstacle segment, a (2*half+1)^2 square marked BLOCKED at each step.
    The squares' union is, on each row, one run of cells (the line moves at most one cell per
    step along each axis): the steps widen each row's run, then each run is marked once."""
    cdef int i0 = to_cell(x0), j0 = to_cell(y0), i1 = to_cell(x1), j1 = to_cell(y1)
    cdef int steps = max(abs(i1 - i0), abs(j1 - j0)), s, i = i0, j = j0, a, b
    cdef int top = max(min(i0, i1) - half, 0), bottom = min(max(i0, i1) + half + 1, GRID)
    cdef int low[GRID]
    cdef int high[GRID]
    mark_tiles(tiles, min(i0, i1) - half, max(i0, i1) + half, min(j0, j1) - half, max(j0, j1) + half)
    for a in range(top, bottom):
        low[a], high[a] = GRID, 0
    for s in range(steps + 1):
        if steps:
            line_cell(i0, j0, i1 - i0, j1 - j0, steps, s, &i, &j)
        for a in range(max(i - half, 0), min(i + half + 1, GRID)):
            low[a] = min(low[a], max(j - half, 0))
            high[a] = max(high[a], min(j + half + 1, GRID))
    for a in range(top, bottom):
        for b in range(low[a], high[a]):
            grid[a * GRID + b] |= BLOCKED


cdef struct Runs:
    # Per tile row: the runs of consecutive marked tiles, as cell columns [start, end).
    int count[TILES]
    int start[TILES][TILES]
    int end[TILES][TILES]


cdef void find_runs(const unsigned char* tiles, Runs* runs) noexcept nogil:
    cdef int ti, tj
    for ti in range(TILES):
        runs.count[ti] = 0
        for tj in range(TILES):
            if not tiles[ti * TILES + tj]:
                continue
            if runs.count[ti] and runs.end[ti][runs.count[ti] - 1] == tj * TILE:
                runs.end[ti][runs.count[ti] - 1] = min(tj * TILE + TILE, GRID)
            else:
                runs.start[ti][runs.count[ti]] = tj * TILE
                runs.end[ti][runs.count[ti]] = min(tj * TILE + TILE, GRID)
                runs.count[ti] += 1


cdef void paint_row(unsigned char* g, int i, int a, int b) noexcept nogil:
    """On cells [a, b) of row i: ROAD where a CENTRE lies within one cell, and VALID unless BLOCKED."""
    cdef unsigned char near[GRID + 2]  # near[k]: CENTRE in column a-1+k of rows i-1 ... i+1
    cdef unsigned char* row = g + i * GRID
    cdef const unsigned char* above = row - GRID if i > 0 else row  # off the grid: the row itself
    cdef const unsigned char* below = row + GRID if i < GRID - 1 else row
    cdef Py_ssize_t k, n = b - a
    near[0] = (above[a - 1] | row[a - 1] | below[a - 1]) if a > 0 else 0
    near[n + 1] = (above[b] | row[b] | below[b]) if b < GRID else 0
    row, above, below = row + a, above + a, below + a  # the loops below start at 0: vectorised
    for k in range(n):
        near[k + 1] = above[k] | row[k] | below[k]
    for k in range(n):
        # branch-free: 0xff when a CENTRE is near, then ROAD | (VALID unless BLOCKED)
        row[k] |= <unsigned char>(-((near[k] | near[k + 1] | near[k + 2]) >> 7)) & (ROAD | (((row[k] >> 6) & 1) ^ VALID))


cdef void finish_row(unsigned char* g, int i, int a, int b) noexcept nogil:
    """On cells [a, b) of row i (rows i-1 ... i+1 painted): FREE where the cell and its 4
    neighbours are VALID, never on the map's edge; clears the scratch bits."""
    cdef unsigned char free_run[GRID]  # a separate buffer keeps the loops vectorisable
    cdef unsigned char* row = g + i * GRID
    cdef int j, lo = max(a, 1), hi = min(b, GRID - 1)
    for j in range(a, b):
        free_run[j] = 0
    if 0 < i < GRID - 1:
        for j in range(lo, hi):
            # (cell & up & down & left & right & VALID) is 0 or 1; shift it onto the FREE bit.
            free_run[j] = (row[j] & row[j - GRID] & row[j + GRID] & row[j - 1] & row[j + 1] & VALID) << 1
    for j in range(a, b):
        row[j] = (row[j] & ~(CENTRE | BLOCKED)) | free_run[j]


def rasterise_track(const double[:, ::1] inner, const double[:, ::1] outer,
                    const double[:, :, ::1] obstacles, int obstacle_half):
    """The track's grid: road from the segments inner[k] -> outer[k] (3x3 brush), obstacles
    (a (2*obstacle_half+1) square brush along each segment) cleared from VALID, and FREE."""
    if obstacle_half < 0:
        raise ValueError(f"obstacle_half must be >= 0, got {obstacle_half}")
    grid = np.zeros((GRID, GRID), dtype=np.uint8)
    cdef unsigned char[:, ::1] view = grid
    cdef unsigned char* g = &view[0, 0]
    cdef unsigned char tiles[TILES * TILES]
    cdef Runs* runs = <Runs*>malloc(sizeof(Runs))
    if runs == NULL:
        raise MemoryError()
    cdef Py_ssize_t k
    cdef int i, r, t
    with nogil:
        memset(tiles, 0, TILES * TILES)
        for k in range(inner.shape[0]):
            trace_road(g, inner[k, 0], inner[k, 1], outer[k, 0], outer[k, 1], tiles)
        for k in range(obstacles.shape[0]):
            trace_obstacle(g, obstacles[k, 0, 0], obstacles[k, 0, 1], obstacles[k, 1, 0], obstacles[k, 1, 1],
                           obstacle_half, tiles)
        find_runs(tiles, runs)
        # One sweep: paint row i, then finish row i - 1 (its neighbours are painted by then).
        for i in range(GRID + 1):
            if i < GRID:
                t = i // TILE
                for r in range(runs.count[t]):
                    paint_row(g, i, runs.start[t][r], runs.end[t][r])
            if i > 0:
                t = (i - 1) // TILE
                for r in range(runs.count[t]):
                    finish_row(g, i - 1, runs.start[t][r], runs.end[t][r])
    free(runs)
    return grid


# -- lidar -----------------------------------------------------------------------------------
cdef double ray_length(const unsigned char* grid, double x, double y, double dx, double dy) noexcept nogil:
    """March along a unit direction: 10 steps of 1/250, then 1/100, then refine by 1/500.

    Returns the distance of the last free point: the first blocked point lies within 1/500 past it.
    """
    cdef int k
    cdef double d = 0.0, step = LIDAR_FINE_STEP, nd
    for k in range(1, LIDAR_FINE_STEPS + 1):
        nd = k * LIDAR_FINE_STEP
        if not cell_has(grid, x + nd * dx, y + nd * dy, FREE):
            break
        d = nd
    else:
        step = LIDAR_COARSE_STEP
        while True:
            nd = d + LIDAR_COARSE_STEP
            if not cell_has(grid, x + nd * dx, y + nd * dy, FREE):
                break
            d = nd
    # The point d + step is blocked: find the last free point before it, 1/500 at a time.
    for k in range(<int>(step / LIDAR_REFINE_STEP + 0.5) - 1):
        nd = d + LIDAR_REFINE_STEP
        if not cell_has(grid, x + nd * dx, y + nd * dy, FREE):
            break
        d = nd
    return d


# Ray offsets from the heading: N_RAYS rays over [-MAX_TURN, +MAX_TURN], counter-clockwise.
cdef double RAY_COS[N_RAYS]
cdef double RAY_SIN[N_RAYS]
cdef int _m
for _m in range(N_RAYS):
    RAY_COS[_m] = cos(ray_angle(_m))
    RAY_SIN[_m] = sin(ray_angle(_m))


cdef inline double ray_angle(int m) noexcept nogil:
    return -MAX_TURN + m * (2 * MAX_TURN) / (N_RAYS - 1)


cdef void scan(const unsigned char* grid, double x, double y, double heading, double* out) noexcept nogil:
    cdef double ch = cos(heading), sh = sin(heading)
    cdef int m
    for m in range(N_RAYS):
        out[m] = ray_length(grid, x, y, ch * RAY_COS[m] - sh * RAY_SIN[m], sh * RAY_COS[m] + ch * RAY_SIN[m])


def lidar(const unsigned char[:, ::1] grid, double x, double y, double heading):
    """The N_RAYS lidar readings of a car at (x, y) with the given heading, on a track grid."""
    out = np.empty(N_RAYS, dtype=np.float64)
    cdef double[::1] view = out
    scan(&grid[0, 0], x, y, heading, &view[0])
    return out


cdef void write_observation(const double* rays, double speed, bint compact, float* obs) noexcept nogil:
    """Compact: [direction, left, max, right, speed]; lidar: N_RAYS readings + speed."""
    cdef int m, k = 0
    if not compact:
        for m in range(N_RAYS):
            obs[m] = <float>rays[m]
        obs[N_RAYS] = <float>speed
        return
    for m in range(1, N_RAYS):
        if rays[m] > rays[k]:
            k = m
    obs[0] = <float>ray_angle(k)
    obs[1] = <float>rays[k - 1 if k > 0 else k]
    obs[2] = <float>rays[k]
    obs[3] = <float>rays[k + 1 if k < N_RAYS - 1 else k]
    obs[4] = <float>speed


# -- cars ------------------------------------------------------------------------------------
cdef const unsigned char* grid_data(grid) except NULL:
    if (not isinstance(grid, np.ndarray) or grid.dtype != np.uint8 or grid.shape != (GRID, GRID)
            or not grid.flags.c_contiguous):
        raise ValueError(f"a track grid must be a C-contiguous uint8 array of shape ({GRID}, {GRID})")
    return <const unsigned char*>cnp.PyArray_DATA(grid)


cdef class CarBatch:
    """N cars advanced together (SPEC 'Car'), all on one track (a race) or each on its own
    (independent episodes: a vector env, a batched evaluation).

    `reset` puts every car at one start on one grid; `place` starts car c's own episode on its
    grid. Arrays are exposed read-only-by-convention to Python (positions for rendering and
    replays, outcomes, observations); all per-step bookkeeping happens here in C. The physics
    numbers may change between steps (the thesis' writable `Racer.tstep`, `Racer.max_acc`...).
    """
    cdef readonly cnp.ndarray x, y, heading, speed, theta, outcome, rays, obs, reward
    cdef readonly cnp.ndarray distance, finish_time, steps_taken
    cdef readonly list grids  # each car's track grid (None before it starts)
    cdef public double tstep, max_acc, max_turn
    cdef public bint turn_limit, low_speed_termination
    cdef readonly bint compact
    cdef readonly int n, obs_dim
    cdef readonly long steps  # step calls since the last `reset`
    cdef const unsigned char** gs
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

    def __cinit__(self, int n, **options):
        if n < 1:
            raise ValueError(f"the number of cars must be >= 1, got {n}")
        self.gs = <const unsigned char**>malloc(n * sizeof(unsigned char*))
        if self.gs == NULL:
            raise MemoryError()

    def __dealloc__(self):
        free(self.gs)

    def __init__(self, int n, *, double tstep, bint turn_limit, bint low_speed_termination, bint compact,
                 double max_acc=MAX_ACC, double max_turn=MAX_TURN):
        self.n = n
        self.tstep, self.max_acc, self.max_turn = tstep, max_acc, max_turn
        self.turn_limit, self.low_speed_termination, self.compact = turn_limit, low_speed_termination, compact
        self.obs_dim = COMPACT_DIM if compact else LIDAR_DIM
        self.grids = [None] * n
        self.x, self.y, self.heading, self.speed, self.theta = [np.zeros(n) for _ in range(5)]
        self.distance, self.finish_time, self.reward = np.zeros(n), np.full(n, np.nan), np.zeros(n)
        self.steps_taken = np.zeros(n, dtype=np.int_)
        self.outcome = np.full(n, RETIRED, dtype=np.int8)  # no car runs before it starts
        self.rays = np.zeros((n, N_RAYS))
        self.obs = np.zeros((n, self.obs_dim), dtype=np.float32)
        for c in range(n):
            self.gs[c] = NULL
        self.xs, self.ys = <double*>cnp.PyArray_DATA(self.x), <double*>cnp.PyArray_DATA(self.y)
        self.hs, self.vs = <double*>cnp.PyArray_DATA(self.heading), <double*>cnp.PyArray_DATA(self.speed)
        self.ts, self.ds = <double*>cnp.PyArray_DATA(self.theta), <double*>cnp.PyArray_DATA(self.distance)
        self.ft, self.rw = <double*>cnp.PyArray_DATA(self.finish_time), <double*>cnp.PyArray_DATA(self.reward)
        self.ry, self.taken = <double*>cnp.PyArray_DATA(self.rays), <long*>cnp.PyArray_DATA(self.steps_taken)
        self.oc, self.ob = <signed char*>cnp.PyArray_DATA(self.outcome), <float*>cnp.PyArray_DATA(self.obs)

    def reset(self, double x, double y, double heading, double speed, grid=None):
        """Put every car at the same start with the same speed, on `grid` (default: where it is)."""
        cdef int c
        if grid is not None:
            self.grids = [grid] * self.n
        if any(g is not self.grids[0] for g in self.grids):
            raise ValueError("the cars are on different tracks: give reset() the grid of their race")
        cdef const unsigned char* g = grid_data(self.grids[0])
        self.steps = 0
        scan(g, x, y, heading, self.ry)
        for c in range(self.n):
            self.start(c, g, x, y, heading, speed, c > 0)

    def place(self, int c, grid, double x, double y, double heading, double speed):
        """Start car c's own episode on a track grid (the other cars carry on)."""
        if not 0 <= c < self.n:
            raise IndexError(f"car {c} is not in a batch of {self.n}")
        cdef const unsigned char* g = grid_data(grid)
        self.grids[c] = grid
        self.start(c, g, x, y, heading, speed, False)

    def set_grid(self, int c, grid):
        """Car c drives on another track grid from its next step, from where it stands."""
        if not 0 <= c < self.n:
            raise IndexError(f"car {c} is not in a batch of {self.n}")
        self.gs[c] = grid_data(grid)
        self.grids[c] = grid

    cdef void start(self, int c, const unsigned char* g, double x, double y, double heading, double speed,
                    bint copy_first_rays):
        self.gs[c] = g
        self.xs[c], self.ys[c], self.hs[c], self.vs[c], self.ts[c] = x, y, heading, speed, atan2(y, x)
        self.ds[c], self.ft[c], self.rw[c], self.taken[c], self.oc[c] = 0.0, NAN, 0.0, 0, RUNNING
        if copy_first_rays:  # a race: every car has the first car's start
            self.rays[c, :] = self.rays[0, :]
        else:
            scan(g, x, y, heading, self.ry + c * N_RAYS)
        write_observation(self.ry + c * N_RAYS, speed, self.compact, self.ob + c * self.obs_dim)

    def step(self, const float[:, ::1] actions, moving=None):
        """Advance every running car by one step; actions (n, 2) [acceleration, turn]. With
        `moving` (bool, n), only those cars act; the others stand still (reward 0).

        Updates obs (a crashed car keeps its last valid observation), reward, outcome,
        distance, steps_taken and, for a car finishing in this step, finish_time
        interpolated inside the step. Returns the number of cars still running.
        """
        cdef bint everyone = moving is None  # the common case: no mask to build or read
        cdef const unsigned char[::1] acts = None if everyone else self._moving(moving)
        if actions.shape[0] != self.n or actions.shape[1] != 2:
            raise ValueError(f"actions must have shape ({self.n}, 2), got ({actions.shape[0]}, {actions.shape[1]})")
        cdef const unsigned char* mask = NULL
        if not everyone:
            mask = &acts[0]
        return self.advance(&actions[0, 0], mask)

    cdef int advance(self, const float* actions, const unsigned char* moving) except -1:
        """`step` on raw arrays: actions (n, 2) row-major, `moving` (n) or NULL for every car."""
        cdef int c, running = 0
        for c in range(self.n):
            if (self.oc[c] == RUNNING and (moving == NULL or moving[c])
                    and (isnan(actions[2 * c]) or isnan(actions[2 * c + 1]))):
                raise ValueError(f"the action of car {c} contains NaN; actions must be finite numbers in [-1, 1]")
        self.steps += 1
        with nogil:
            for c in range(self.n):
                self.rw[c] = 0.0
                if self.oc[c] == RUNNING and (moving == NULL or moving[c]):
                    self.move(c, actions[2 * c], actions[2 * c + 1])
                running += self.oc[c] == RUNNING
        return running

    def _moving(self, moving) -> cnp.ndarray:
        moving = np.asarray(moving, dtype=bool)
        if moving.shape != (self.n,):
            raise ValueError(f"moving must have shape ({self.n},), got {moving.shape}")
        return moving.view(np.uint8)

    def step_episodes(self, const float[:, ::1] actions, long max_steps, moving=None):
        """`step` for cars in independent episodes: returns (terminated, truncated), bool arrays
        of the cars that stopped in this step, and of those still running that have now taken
        `max_steps` steps of their own episode (cars outside `moving` are neither)."""
        running_before = self.outcome == RUNNING
        if moving is not None:
            moving = self._moving(moving).view(bool)
            running_before &= moving
        self.step(actions, moving)
        terminated, truncated = np.zeros(self.n, dtype=bool), np.zeros(self.n, dtype=bool)
        cdef const unsigned char[::1] before = running_before.view(np.uint8)
        cdef unsigned char[::1] stopped = terminated.view(np.uint8), timed_out = truncated.view(np.uint8)
        cdef int c
        for c in range(self.n):
            if before[c]:
                stopped[c] = self.oc[c] != RUNNING
                timed_out[c] = self.oc[c] == RUNNING and self.taken[c] >= max_steps
        return terminated, truncated

    def step_vector(self, cnp.ndarray actions, long max_steps, cnp.ndarray pending, bint refuse_pending=False,
                    bint names=True, dict masks=None):
        """`step_episodes` of every car and `observe`, for the vector env's step, in one call:
        `actions` a C-contiguous float32 (n, 2) array (league.cars.as_actions), `pending` the
        bool (n) array of the cars whose episode ended in an earlier step and is still to be
        restarted.

        Returns (obs, rewards, terminated, truncated, infos, n_done, n_pending): new arrays (a
        copy of `reward` and step_episodes' flags), the number of cars that stopped or ran out of
        time in this step and the number pending before it; obs and infos are `observe(None,
        names, masks)`'s, or None when either number is not 0 (episodes to end or restart
        first). With `refuse_pending` and a car pending, returns None before anything moves.
        """
        if (cnp.PyArray_TYPE(actions) != cnp.NPY_FLOAT32 or actions.ndim != 2 or actions.shape[0] != self.n
                or actions.shape[1] != 2 or not cnp.PyArray_IS_C_CONTIGUOUS(actions)):
            raise ValueError(f"actions must be a C-contiguous float32 array of shape ({self.n}, 2)")
        if (cnp.PyArray_TYPE(pending) != cnp.NPY_BOOL or pending.ndim != 1 or pending.shape[0] != self.n
                or not cnp.PyArray_IS_C_CONTIGUOUS(pending)):
            raise ValueError(f"pending must be a C-contiguous bool array of shape ({self.n},)")
        cdef const unsigned char* waiting = <const unsigned char*>cnp.PyArray_DATA(pending)
        cdef int c, n_done = 0, n_pending = 0
        for c in range(self.n):
            n_pending += waiting[c] != 0
        if refuse_pending and n_pending:
            return None
        cdef cnp.npy_intp dims[1]
        dims[0] = self.n
        terminated = cnp.PyArray_ZEROS(1, dims, cnp.NPY_BOOL, 0)
        truncated = cnp.PyArray_ZEROS(1, dims, cnp.NPY_BOOL, 0)
        cdef unsigned char* stopped = <unsigned char*>cnp.PyArray_DATA(terminated)
        cdef unsigned char* timed_out = <unsigned char*>cnp.PyArray_DATA(truncated)
        for c in range(self.n):
            timed_out[c] = self.oc[c] == RUNNING  # running before the step, for now
        self.advance(<const float*>cnp.PyArray_DATA(actions), NULL)
        for c in range(self.n):
            if timed_out[c]:
                stopped[c] = self.oc[c] != RUNNING
                timed_out[c] = self.oc[c] == RUNNING and self.taken[c] >= max_steps
                n_done += stopped[c] | timed_out[c]
        rewards = cnp.PyArray_EMPTY(1, dims, cnp.NPY_FLOAT64, 0)
        memcpy(cnp.PyArray_DATA(rewards), self.rw, self.n * sizeof(double))
        if n_done or n_pending:
            return None, rewards, terminated, truncated, None, n_done, n_pending
        obs, infos = self.observe(None, names, masks)
        return obs, rewards, terminated, truncated, infos, n_done, n_pending

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
        cdef const unsigned char* g = self.gs[c]
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
        if not cell_has(g, nx, ny, VALID):
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
            self.ft[c] = (self.taken[c] - 1 + th / (th - nt)) * self.tstep
        self.xs[c], self.ys[c], self.hs[c], self.vs[c], self.ts[c] = nx, ny, h, v, nt
        scan(g, nx, ny, h, self.ry + c * N_RAYS)
        write_observation(self.ry + c * N_RAYS, v, self.compact, self.ob + c * self.obs_dim)

    def __reduce__(self):
        options = dict(tstep=self.tstep, turn_limit=self.turn_limit, low_speed_termination=self.low_speed_termination,
                       compact=self.compact, max_acc=self.max_acc, max_turn=self.max_turn)
        state = {name: getattr(self, name).copy() for name in STATE_ARRAYS}
        state["steps"] = self.steps
        return (_restore_car_batch, (self.n, options, self.grids, state))

    def _set_state(self, list grids, dict state):
        for name in STATE_ARRAYS:
            np.copyto(getattr(self, name), state[name])
        self.steps = state["steps"]
        for c, grid in enumerate(grids):
            self.grids[c] = grid
            if grid is not None:
                self.gs[c] = grid_data(grid)

    def retire(self, int c):
        """Take car c out of the race where it stands; it is done, with outcome "retired"."""
        if self.oc[c] == RUNNING:
            self.oc[c] = RETIRED

    def observation(self, int c):
        """A copy of car c's observation."""
        return self.obs[c].copy()

    cdef double lap_progress(self, int c) noexcept nogil:
        if self.oc[c] == FINISHED:
            return 1.0
        cdef double p = fmod(-self.ts[c], 2 * M_PI)
        return (p + 2 * M_PI if p < 0 else p) / (2 * M_PI)

    def progress(self, int c):
        """Fraction of the lap covered, from the polar angle (the race runs clockwise from 0)."""
        return self.lap_progress(c)

    def progress_all(self):
        """`progress` of every car, as an array."""
        out = np.empty(self.n)
        cdef double[::1] view = out
        cdef int c
        for c in range(self.n):
            view[c] = self.lap_progress(c)
        return out

    def observe(self, shown_running=None, bint names=True, dict masks=None):
        """A copy of every car's observation and their infos as arrays, those of `info` (dtypes
        int64 and float64, "outcome" an object array of names, left out without `names`), then
        the items of `masks`; cars in the bool (n) array `shown_running` are reported as running
        (out of time, not stopped)."""
        cdef cnp.npy_intp dims[2]
        dims[0], dims[1] = self.n, self.obs_dim
        obs = cnp.PyArray_EMPTY(2, dims, cnp.NPY_FLOAT32, 0)
        memcpy(cnp.PyArray_DATA(obs), self.ob, self.n * self.obs_dim * sizeof(float))
        codes = cnp.PyArray_EMPTY(1, dims, cnp.NPY_INT64, 0)
        progress = cnp.PyArray_EMPTY(1, dims, cnp.NPY_FLOAT64, 0)
        times = cnp.PyArray_EMPTY(1, dims, cnp.NPY_FLOAT64, 0)
        distance = cnp.PyArray_EMPTY(1, dims, cnp.NPY_FLOAT64, 0)
        speed = cnp.PyArray_EMPTY(1, dims, cnp.NPY_FLOAT64, 0)
        cdef const unsigned char* shown = NULL
        if shown_running is not None:
            if (not isinstance(shown_running, np.ndarray) or shown_running.dtype != np.bool_
                    or shown_running.shape != (self.n,) or not shown_running.flags.c_contiguous):
                raise ValueError(f"shown_running must be a C-contiguous bool array of shape ({self.n},)")
            shown = <const unsigned char*>cnp.PyArray_DATA(shown_running)
        cdef cnp.int64_t* code = <cnp.int64_t*>cnp.PyArray_DATA(codes)
        cdef double* p = <double*>cnp.PyArray_DATA(progress)
        cdef double* t = <double*>cnp.PyArray_DATA(times)
        cdef int c
        for c in range(self.n):
            code[c] = RUNNING if shown != NULL and shown[c] else self.oc[c]
            p[c] = self.lap_progress(c)
            t[c] = self.taken[c] * self.tstep  # numpy's steps_taken * tstep: the int as a double, times tstep
        memcpy(cnp.PyArray_DATA(distance), self.ds, self.n * sizeof(double))
        memcpy(cnp.PyArray_DATA(speed), self.vs, self.n * sizeof(double))
        infos = {}
        if names:
            infos["outcome"] = outcome_names(code, self.n)
        infos["outcome_code"] = codes
        infos["progress"] = progress
        infos["time"] = times
        infos["distance"] = distance
        infos["speed"] = speed
        if masks:
            infos.update(masks)
        return obs, infos

    def info(self, int c):
        """Car c's outcome (name and code), lap progress, time (s), distance and speed.

        Numbers are numpy scalars: libraries read an info value's dtype (torchrl's info reader).
        """
        cdef int code = self.oc[c]
        return {
            "outcome": OUTCOMES[code],
            "outcome_code": OUTCOME_CODES[code],
            "progress": float64(self.lap_progress(c)),
            "time": float64(self.taken[c] * self.tstep),
            "distance": float64(self.ds[c]),
            "speed": float64(self.vs[c]),
        }


cdef tuple OUTCOME_NAMES = tuple(OUTCOMES)


cdef object outcome_names(const cnp.int64_t* codes, int n):
    """An object array of the outcomes' names (numpy's `np.array(OUTCOMES, dtype=object)[codes]`)."""
    cdef cnp.npy_intp dims[1]
    dims[0] = n
    names = cnp.PyArray_EMPTY(1, dims, cnp.NPY_OBJECT, 0)  # every item None
    cdef PyObject** items = <PyObject**>cnp.PyArray_DATA(names)
    cdef PyObject* name
    cdef int c
    for c in range(n):
        name = <PyObject*>OUTCOME_NAMES[codes[c]]
        Py_INCREF(<object>name)
        Py_XDECREF(items[c])
        items[c] = name
    return names


STATE_ARRAYS = ("x", "y", "heading", "speed", "theta", "outcome", "rays", "obs", "reward",
                "distance", "finish_time", "steps_taken")


def _restore_car_batch(n, options, grids, state):
    """Unpickle a CarBatch (its state arrays are copied in)."""
    cars = CarBatch(n, **options)
    cars._set_state([None if g is None else np.ascontiguousarray(g) for g in grids], state)
    return cars
