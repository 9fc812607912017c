"""The numbers of MicroRacer, written once (SPEC "Track", "Car", "Lidar and observation").

This module imports nothing: setup.py reads it before anything is built and compiles its numbers
into the core (league/lidar.pyx, through Cython's ``compile_time_env``), and every Python module
takes them from here. Change a number here, then rebuild: ``python setup.py build_ext --inplace``.
"""
import math

# -- versions -------------------------------------------------------------------------------
# Bump when dynamics, rewards or observations change: evaluation results of another physics
# version are never compared with this one's (league.evaluation.result_key).
PHYSICS_VERSION = 1
TRACK_FORMAT_VERSION = 1  # of Track.to_dict: a saved track of another format is refused

# -- map ----------------------------------------------------------------------------------
GRID = 1300  # cells per side of the square map
ORIGIN = GRID // 2  # cell of world coordinate 0: cell = int(x * CELLS_PER_UNIT) + ORIGIN
CELLS_PER_UNIT = 500  # cells per world unit (1 unit = 1000 m)
MAP_EXTENT = ORIGIN / CELLS_PER_UNIT  # world units from the centre to the map's edge (1.3)

# -- track ----------------------------------------------------------------------------------
CURVES = 20  # control points of the mid-line
CURVES_RANGE = (5, 60)  # beyond these a track takes long to draw
TRACK_WIDTH = 0.04  # world units (1 unit = 1000 m)
MAX_TRACK_WIDTH = 0.08  # wider borders fold on tight bends
N_OBSTACLES = 6
N_OBSTACLES_RANGE = (0, 20)
BORDER_SAMPLES_PER_CURVE = 6  # mid-line samples per control point, for the borders
RASTER_ANGLES = 2000  # inner -> outer segments drawn on the map
OBSTACLE_LENGTH = math.pi / 150  # angular length of an obstacle (rad)
CHICANE_OUTER, CHICANE_INNER = 1 / 3, 1 / 25  # chicane points at theta[c] +- delta * these
CHICANE_PUSH = 0.02  # the chicane's inner pair is pushed apart by +-2 %
CHICANE_ADDED_POINTS = 4  # a chicane replaces one control point by five
MAX_DRAWS = 100  # tracks drawn before giving up (a discarded track is very rare)

# -- car ----------------------------------------------------------------------------------
TSTEP = 0.04  # seconds per step
MAX_ACC = 0.1  # world units / s^2 at full throttle
MAX_TURN = math.pi / 6  # rad per step at full lock; also the widest lidar angle
TURN_LIMIT_COEFF = 1.741  # with the turn limiter: turn bound = min(MAX_TURN, 1.741 * tstep / speed)
MIN_SPEED = 0.05  # world units / s: slower ends the episode with low-speed termination on
CRASH_REWARD = -3.0  # off road, wrong direction or too slow

# Outcome codes of a car, the index of its name in OUTCOMES.
RUNNING, FINISHED, OFF_ROAD, WRONG_DIRECTION, TOO_SLOW, RETIRED = range(6)
OUTCOMES = ("running", "finished", "off_road", "wrong_direction", "too_slow", "retired")
# What results, tables and pictures say of an outcome: a car's, or an evaluation's and a race's
# "timeout" (still running at the episode limit) and "dnf" (its agent failed).
OUTCOME_TEXT = {
    "finished": "finished",
    "off_road": "off road",
    "wrong_direction": "wrong direction",
    "too_slow": "too slow",
    "timeout": "out of time",
    "dnf": "agent failed",
}

# -- episodes -------------------------------------------------------------------------------
START_SPEED_MAX = 0.5  # initial speed ~ U(0, 0.5)
START_SPEED_FLOOR = 0.07  # with low-speed termination on
MAX_EPISODE_STEPS = 4000  # 160 s: a lap at the lowest allowed speed (0.05) still fits
# What a course can use besides the track's own ranges (CURVES_RANGE, N_OBSTACLES_RANGE): beyond
# these an episode makes a huge replay.
EPISODE_STEPS_RANGE = (1, 20_000)  # a lap at the lowest speed (0.05) fits even at tstep 0.01
TSTEP_RANGE = (0.01, 0.2)  # seconds
# Episode starts kept per process by league.track.episode_start. A track holds its 1300 x 1300
# map (1.69 MB) once a car has driven on it, so the cache holds at most ~220 MB.
TRACK_CACHE_SIZE = 128

# -- lidar and observations -----------------------------------------------------------------
N_RAYS = 19  # equally spaced over [-MAX_TURN, +MAX_TURN] around the heading
LIDAR_FINE_STEPS = 10  # march steps of LIDAR_FINE_STEP before switching to LIDAR_COARSE_STEP
LIDAR_FINE_STEP = 1 / 250  # world units
LIDAR_COARSE_STEP = 1 / 100
LIDAR_REFINE_STEP = 1 / 500  # the reading's accuracy
MAX_LIDAR_RANGE = 3.7  # no reading exceeds the map's diagonal (world units)
MAX_SPEED = 50.0  # the speed's bound in the observation spaces: no car reaches it (0.1 * 0.04 * 4000 + 0.5 = 16.5)
COMPACT_DIM = 5  # [direction, left, max, right, speed]
LIDAR_DIM = N_RAYS + 1  # the readings and the speed
OBSERVATION_DIMS = {"compact": COMPACT_DIM, "lidar": LIDAR_DIM}  # observation name -> numbers per observation
OBSERVATIONS = tuple(OBSERVATION_DIMS)

# -- model files ----------------------------------------------------------------------------
MODEL_SUFFIXES = {".onnx": "onnx", ".pt": "torchscript", ".pth": "torchscript", ".ts": "torchscript",
                  ".jit": "torchscript", ".torchscript": "torchscript"}
PICKLE_MARK = b"\x80"  # first byte of every pickle of protocol >= 2
ZIP_MAGIC = b"PK\x03\x04"  # first bytes of a zip archive (TorchScript files are zips)


def observation_name(obs_dim: int) -> str:
    """The observation ("compact" or "lidar") of `obs_dim` numbers; ValueError for another size."""
    for name, dim in OBSERVATION_DIMS.items():
        if obs_dim == dim:
            return name
    raise ValueError(f"an observation has {COMPACT_DIM} numbers (compact) or {LIDAR_DIM} (lidar), not {obs_dim!r}")


def is_pickle(head: bytes) -> bool:
    """Whether a file that starts with `head` is a pickle (of protocol >= 2): never loaded."""
    return head[:1] == PICKLE_MARK


def is_zip(head: bytes) -> bool:
    """Whether a file that starts with `head` is a zip archive (what a TorchScript file is)."""
    return head[:4] == ZIP_MAGIC


def is_torchscript_layout(names: list[str]) -> bool:
    """Whether a zip archive's entry names are TorchScript's (code/ and constants.pkl), not a
    torch.save checkpoint's (a pickle in a zip)."""
    return any("/code/" in name for name in names) and any(name.endswith("constants.pkl") for name in names)


def compiled() -> dict:
    """The numbers the compiled core is built with (setup.py passes them to Cython)."""
    return {name: value for name, value in globals().items()
            if name.isupper() and type(value) in (int, float)}
