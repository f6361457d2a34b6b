#!/usr/bin/env bash
# pip install --no-build-isolation . works offline: from a copy of the tracked files
# (so the checkout is not written to), into a scratch --target, importable from there.
#   pip_install_test.sh SOURCE_DIR PYTHON BUILD_DIR
# The library is this build's, installed into a scratch prefix: pip compiles only the
# bindings against it (MESHPDE_PYTHON_USE_INSTALLED, the route for a machine whose
# C++ library is installed already). The library itself is compiled by the same CMake
# files in every build; what this test adds is setup.py, pyproject.toml and the
# module's install rules, which both routes share.
set -euo pipefail
src="$1"
python="$2"
build="$3"
T="$(mktemp -d)"
trap 'rm -rf "$T"' EXIT
mkdir "$T/src"
# The tracked files and the page's sources only: no build trees, no node_modules.
(cd "$src" && git ls-files -z --cached --others --exclude-standard 2>/dev/null | xargs -0 cp --parents -t "$T/src") ||
  cp -r "$src"/{CMakeLists.txt,setup.py,pyproject.toml,cmake,include,src,python,docs} "$T/src"
"$python" -c "import setuptools" 2>/dev/null || { echo "python3-setuptools missing"; exit 1; }
"$python" -m pip --version >/dev/null 2>&1 || { echo "pip missing (Debian: python3-pip)"; [ "${CI:-}" = true ] && exit 1; exit 77; }
cmake --install "$build" --prefix "$T/prefix" >/dev/null
# The bindings without optimization or debug information: what is tested is the
# packaging, and they compile in about half the time.
(cd "$T/src" && PIP_NO_INDEX=1 MESHPDE_CMAKE_ARGS="-DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-O0 -DMESHPDE_PYTHON_USE_INSTALLED=ON -DCMAKE_PREFIX_PATH=$T/prefix ${MESHPDE_CMAKE_ARGS:-}" \
   "$python" -m pip install --no-build-isolation --no-deps --verbose --target "$T/site" . >"$T/log" 2>&1) ||
  { tail -40 "$T/log"; exit 1; }
# The installed library was used, not compiled again.
grep -q "Python module against the installed meshpde in $T/prefix" "$T/log" ||
  { echo "pip did not build against the installed meshpde:"; grep -i "meshpde" "$T/log" | head -20; exit 1; }
if grep -q "src/CMakeFiles/meshpde.dir" "$T/log"; then echo "pip compiled the library again"; exit 1; fi
medical=0
ls "$T"/prefix/lib*/libmeshpde_medical.* >/dev/null 2>&1 && medical=1
cd "$T"
PYTHONPATH="$T/site" "$python" -c "
import meshpde, sys
assert meshpde.__file__.startswith(sys.argv[1]), meshpde.__file__
V, F = meshpde.generate.icosphere(2)
assert abs(meshpde.stiffness(V, F) @ V[:, 0]).max() > 0
assert meshpde.has_medical == bool(int(sys.argv[2])), ('has_medical', meshpde.has_medical, 'installed', sys.argv[2])
print('pip install: imported meshpde', meshpde.__version__, 'from', meshpde.__file__, 'medical', meshpde.has_medical)" "$T/site" "$medical"
