"""Builds the Python package meshpde with CMake (see pyproject.toml).

The extension _meshpde is built by the project's own CMakeLists.txt with only the
library and the module (no tool, tests or benchmarks) and installed into the wheel's
staging directory. Environment: MESHPDE_CMAKE_ARGS adds CMake arguments,
MESHPDE_JOBS the build's parallelism (default 2).
"""
import os
import pathlib
import re
import shlex
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        out = pathlib.Path(self.get_ext_fullpath(ext.name)).resolve().parent.parent  # the staging root
        build = pathlib.Path(self.build_temp).resolve() / "cmake"
        args = ["-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release", f"-DPython3_EXECUTABLE={sys.executable}",
                "-DMESHPDE_BUILD_CLI=OFF", "-DMESHPDE_BUILD_TESTS=OFF", "-DMESHPDE_BUILD_BENCH=OFF",
                "-DMESHPDE_BUILD_PYTHON=ON", f"-DMESHPDE_PYTHON_INSTALL_DIR={out}"]
        args += shlex.split(os.environ.get("MESHPDE_CMAKE_ARGS", ""))
        subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build), *args], check=True)
        subprocess.run(["cmake", "--build", str(build), "-j", os.environ.get("MESHPDE_JOBS", "2"),
                        "--target", "meshpde_python"], check=True)
        subprocess.run(["cmake", "--install", str(build), "--component", "python"], check=True)


version = re.search(r"project\(meshpde VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text()).group(1)
setup(version=version, packages=[], ext_modules=[CMakeExtension("meshpde._meshpde")],
      cmdclass={"build_ext": CMakeBuild}, zip_safe=False)
