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

# -- map ----------------------------------------------------------------------------------
GRID = 1300  # cells per side of the square map
ORIGIN = GRID // 2  # cell of world coordinate 0: cell = int(x * CELLS_PER_UNIT) + ORIGIN
CELLS_PER_UNIT = 500  # cells per world unit (1 unit = 1000 m)

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

# -- lidar and observations -----------------------------------------------------------------
N_RAYS = 19  # equally spaced over [-MAX_TURN, +MAX_TURN] around the heading
LIDAR_FINE_STEPS = 10  # march steps of LIDAR_FINE_STEP before switching to LIDAR_COARSE_STEP
LIDAR_FINE_STEP = 1 / 250  # world units
LIDAR_COARSE_STEP = 1 / 100
LIDAR_REFINE_STEP = 1 / 500  # the reading's accuracy
COMPACT_DIM = 5  # [direction, left, max, right, speed]
LIDAR_DIM = N_RAYS + 1  # the readings and the speed

# -- model files ----------------------------------------------------------------------------
MODEL_SUFFIXES = {".onnx": "onnx", ".pt": "torchscript", ".pth": "torchscript", ".ts": "torchscript",
                  ".jit": "torchscript", ".torchscript": "torchscript"}
PICKLE_MARK = b"\x80"  # first byte of every pickle of protocol >= 2
ZIP_MAGIC = b"PK\x03\x04"  # first bytes of a zip archive (TorchScript files are zips)


def compiled() -> dict:
    """The numbers the compiled core is built with (setup.py passes them to Cython)."""
    return {name: value for name, value in globals().items()
            if name.isupper() and type(value) in (int, float)}
