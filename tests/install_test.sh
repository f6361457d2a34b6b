#!/usr/bin/env bash
# Installs meshpde from BUILD_DIR into a scratch prefix, then configures and builds
# a consumer project with find_package(meshpde CONFIG REQUIRED) and runs it.
set -euo pipefail
build="$1"
consumer="$2"
T="$(mktemp -d)"
trap 'rm -rf "$T"' EXIT
cmake --install "$build" --prefix "$T/prefix" >/dev/null
test -f "$T/prefix/lib/cmake/meshpde/meshpdeConfigVersion.cmake"
# With the server built and the page built (scripts/build-web), the page is installed
# and the installed tool serves it by default, not the source tree's copy.
if "$T/prefix/bin/meshpde" serve --help >"$T/serve-help" 2>&1; then
  if [ -f "$(dirname "$0")/../web/dist/index.html" ]; then
    test -f "$T/prefix/share/meshpde/web/index.html"
    grep -q -- "--web-root TEXT=$T/prefix/share/meshpde/web\$" "$T/serve-help" ||
      { echo "installed serve does not default to the installed page:"; grep -- --web-root "$T/serve-help"; exit 1; }
  elif [ "${CI:-}" = true ]; then
    echo "web/dist/index.html missing under CI (scripts/build-web builds it)"; exit 1
  fi
fi
# The Python package, when built, is installed under the prefix's site-packages and
# imports from there (its own copy, not the build tree's).
if [ -d "$build/python/meshpde" ]; then
  so="$(find "$T/prefix" -name '_meshpde*.so' | head -1)"
  [ -n "$so" ] || { echo "the Python module was not installed"; exit 1; }
  site="$(dirname "$(dirname "$so")")"
  (cd "$T" && PYTHONPATH="$site" /usr/bin/python3 -c \
    "import meshpde, sys; assert meshpde.__file__.startswith(sys.argv[1]), meshpde.__file__; V, F = meshpde.generate.icosphere(1); assert meshpde.stiffness(V, F).shape == (42, 42)" "$site")
fi
extra=()
# A sanitized static library needs its consumer linked with the same runtime.
if grep -q "MESHPDE_SANITIZE:BOOL=ON" "$build/CMakeCache.txt"; then
  extra=(-DCMAKE_CXX_FLAGS="-fsanitize=address,undefined" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined")
fi
cmake -S "$consumer" -B "$T/build" -G Ninja -DCMAKE_PREFIX_PATH="$T/prefix" "${extra[@]}" >/dev/null
cmake --build "$T/build" >/dev/null
"$T/build/consumer" | tee "$T/out"
grep -q "K 1 = 0" "$T/out"
if ls "$T"/prefix/lib*/libmeshpde_medical.* >/dev/null 2>&1; then
  grep -q "vtp round trip: same" "$T/out"
fi
