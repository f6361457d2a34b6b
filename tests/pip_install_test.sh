#!/usr/bin/env bash
# pip install --no-build-isolation . works offline: from a copy of the tracked files
# (so the checkout is not written to), into a scratch --target, importable from there.
set -euo pipefail
src="$1"
python="$2"
T="$(mktemp -d)"
trap 'rm -rf "$T"' EXIT
mkdir "$T/src"
# The tracked files and the page's sources only: no build trees, no node_modules.
(cd "$src" && git ls-files -z --cached --others --exclude-standard 2>/dev/null | xargs -0 cp --parents -t "$T/src") ||
  cp -r "$src"/{CMakeLists.txt,setup.py,pyproject.toml,cmake,include,src,python,docs} "$T/src"
"$python" -c "import setuptools" 2>/dev/null || { echo "python3-setuptools missing"; exit 1; }
"$python" -m pip --version >/dev/null 2>&1 || { echo "pip missing (Debian: python3-pip)"; [ "${CI:-}" = true ] && exit 1; exit 77; }
# What is tested is the packaging: built without optimization or debug information,
# which compiles in about half the time, and without the VTK-based medical component,
# whose translation units are the slowest to compile (python.pytest tests the Release
# module with it).
(cd "$T/src" && PIP_NO_INDEX=1 MESHPDE_CMAKE_ARGS="-DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-O0 -DMESHPDE_WITH_VTK=OFF ${MESHPDE_CMAKE_ARGS:-}" \
   "$python" -m pip install --no-build-isolation --no-deps --target "$T/site" . >"$T/log" 2>&1) ||
  { tail -40 "$T/log"; exit 1; }
cd "$T"
PYTHONPATH="$T/site" "$python" -c "
import meshpde, sys
assert meshpde.__file__.startswith(sys.argv[1]), meshpde.__file__
V, F = meshpde.generate.icosphere(2)
assert abs(meshpde.stiffness(V, F) @ V[:, 0]).max() > 0
print('pip install: imported meshpde', meshpde.__version__, 'from', meshpde.__file__)" "$T/site"
