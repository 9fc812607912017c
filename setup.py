"""Build the compiled core (league/lidar.pyx) with Cython at install time.

The core's numbers come from league/constants.py (Cython's compile_time_env); its compiler
directives are in the .pyx header.
"""
import runpy
from pathlib import Path

import numpy
from Cython.Build import cythonize
from setuptools import Extension, setup

HERE = Path(__file__).parent
CONSTANTS = HERE / "league" / "constants.py"
GENERATED = HERE / "league" / "lidar.c"

extensions = [
    Extension(
        "league.lidar",
        ["league/lidar.pyx"],
        include_dirs=[numpy.get_include()],
        extra_compile_args=["-O3"],
        define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
    )
]

# Cython regenerates the C file when the .pyx changes; the constants are an input too.
constants_changed = not GENERATED.exists() or CONSTANTS.stat().st_mtime > GENERATED.stat().st_mtime

setup(
    ext_modules=cythonize(
        extensions,
        compile_time_env=runpy.run_path(str(CONSTANTS))["compiled"](),
        force=constants_changed,
    )
)
