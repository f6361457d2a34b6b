#!/usr/bin/env bash
# The distributed component end to end (ctest distributed.mpi): `meshpde partition`
# and `mpirun -n 1|2|4 meshpde-mpi interpolate|fair` against the single-process
# `meshpde interpolate|fair --laplacian cotan` (interpolation on a generated sphere, a
# real mesh and a non-manifold one; fairing with a halfspace or the boundary held), to
# 1e-8 relative, every vertex's value written by exactly one rank, `meshpde-mpi join`'s
# mesh (the input's triangles, the field or positions) equal to the serial output, and
# bad parts, arguments and result folders failing with a message and no hang.
#   distributed_test.sh MESHPDE MESHPDE_MPI PYTHON DATA_DIR
set -euo pipefail
M="$1"; MPI_TOOL="$2"; PY="$3"; DATA="$4"
T="$(mktemp -d)"
trap 'rm -rf "$T"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1   # CI runs as root
export OMPI_MCA_btl=self,vader OMPI_MCA_btl_vader_single_copy_mechanism=none OMPI_MCA_rmaps_base_oversubscribe=1
fail() { echo "FAIL: $*" >&2; exit 1; }
run() { timeout 120 mpirun -n "$1" "${@:2}"; }

for mesh in bunny-3k.off nonmanifold-vierbein.obj; do
  if [ ! -f "$DATA/$mesh" ]; then
    [ "${CI:-}" = true ] && fail "$DATA/$mesh is missing (CI=true needs ../shared/data)"
    echo "skip: $DATA/$mesh not found"; continue
  fi
  cp "$DATA/$mesh" "$T/"
done
"$M" generate icosphere --level 4 -o "$T/sphere.off" >/dev/null

compare() {  # compare SERIAL.ply OUTDIR N PREFIX: the ranks' PREFIX-RANK.csv against the serial answer
  "$PY" - "$1" "$2" "$3" "${4:-u}" <<'PY'
import csv, glob, math, sys
serial, outdir, n, prefix = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
columns = ["u"] if prefix == "u" else ["x", "y", "z"]
# The serial answer: the PLY's property u (ascii or binary: read through the tool's Python-free route below).
import struct
data = open(serial, "rb").read()
head, body = data.split(b"end_header\n", 1)
lines = head.decode().splitlines()
fmt = [l for l in lines if l.startswith("format")][0].split()[1]
nv = int([l for l in lines if l.startswith("element vertex")][0].split()[2])
props = []
inside = False
for l in lines:
    if l.startswith("element"):
        inside = l.split()[1] == "vertex"
    elif l.startswith("property") and inside:
        props.append((l.split()[1], l.split()[2]))
codes = {"float": "f", "double": "d", "float32": "f", "float64": "d", "int": "i", "uchar": "B", "int32": "i"}
assert fmt == "binary_little_endian", fmt
rec = "<" + "".join(codes[t] for t, _ in props)
size = struct.calcsize(rec)
names = [name for _, name in props]
u = [[struct.unpack_from(rec, body, i * size)[names.index(c)] for c in columns] for i in range(nv)]
got = [None] * nv
files = sorted(glob.glob(f"{outdir}/{prefix}-*.csv"))
assert len(files) == n, f"{len(files)} value files for {n} ranks"
for f in files:
    for row in csv.DictReader(open(f)):
        v = int(row["vertex"])
        assert got[v] is None, f"vertex {v} written twice"
        got[v] = [float(row[c]) for c in columns]
missing = [v for v in range(nv) if got[v] is None]
assert not missing, f"{len(missing)} vertices without a value, e.g. {missing[:5]}"
scale = max(abs(x) for r in u for x in r)
rel = max(abs(a - b) for r, s in zip(got, u) for a, b in zip(r, s)) / scale
assert rel < 1e-8, f"{outdir}: relative difference {rel:.3g} to the single-process answer"
print(f"  {outdir}: {n} ranks, relative difference {rel:.2g}")
PY
}

joined() {  # joined SERIAL.ply PARTS OUTDIR u|positions: meshpde-mpi join's mesh against the serial answer
  "$MPI_TOOL" join "$2" "$3" -o "$T/joined.ply" >/dev/null
  "$PY" - "$1" "$T/joined.ply" "$4" <<'PY'
import sys
import meshio, numpy as np
serial, joined, kind = meshio.read(sys.argv[1]), meshio.read(sys.argv[2]), sys.argv[3]
def oriented(mesh):  # each triangle from its smallest corner, orientation kept
    F = mesh.cells_dict["triangle"]
    r = np.argmin(F, axis=1)
    return {tuple(F[i, (r[i] + k) % 3] for k in range(3)) for i in range(len(F))}
assert len(joined.cells_dict["triangle"]) == len(serial.cells_dict["triangle"]), "triangle count"
assert oriented(joined) == oriented(serial), "the joined triangles differ from the input's"
a, b = (joined.point_data["u"], serial.point_data["u"]) if kind == "u" else (joined.points, serial.points)
rel = np.abs(a - b).max() / np.abs(b).max()
assert rel < 1e-8, f"joined {kind}: relative difference {rel:.3g}"
if kind == "u":
    assert np.array_equal(joined.points, serial.points), "the joined positions are not the input's"
print(f"  joined: {len(joined.points)} vertices, {kind} within {rel:.2g}")
PY
}

for mesh in sphere.off bunny-3k.off nonmanifold-vierbein.obj; do
  [ -f "$T/$mesh" ] || continue
  nv=$("$M" info "$T/$mesh" --json | "$PY" -c "import json,sys; print(json.load(sys.stdin)['vertices'])")
  printf "vertex,value\n0,1\n%d,-1\n%d,0.5\n%d,2\n" $((nv / 3)) $((nv / 2)) $((nv - 1)) >"$T/cons.csv"
  "$M" interpolate "$T/$mesh" --constraints "$T/cons.csv" --laplacian cotan -o "$T/serial.ply" >/dev/null
  echo "$mesh ($nv vertices)"
  for n in 1 2 4; do
    "$M" partition "$T/$mesh" --parts $n -o "$T/parts-$n" --json >"$T/partition-report.json"
    run $n "$MPI_TOOL" interpolate "$T/parts-$n" --constraints "$T/cons.csv" -o "$T/out-$n" --json >"$T/report.json"
    "$PY" - "$T/report.json" $n $nv <<'PY'
import json, sys
r, n, nv = json.load(open(sys.argv[1])), int(sys.argv[2]), int(sys.argv[3])
assert r["ranks"] == n and r["vertices"] == nv and len(r["per_rank"]) == n, r
assert sum(x["vertices"] for x in r["per_rank"]) == nv, r["per_rank"]
assert r["result"]["relative_residual"] < 1e-8 and r["result"]["cg_iterations"] > 0, r["result"]
assert all(x["peak_rss_mb"] > 0 and x["solve_seconds"] >= 0 for x in r["per_rank"]), r["per_rank"]
PY
    compare "$T/serial.ply" "$T/out-$n" $n
    joined "$T/serial.ply" "$T/parts-$n" "$T/out-$n" u
  done
done

echo "fair"
# Thin plate with half a sphere held, membrane with the bunny's bottom held, thin plate
# with a tube's rims (its boundary) held.
"$M" generate tube --radius 3 --length 20 --rings 30 --segments 24 -o "$T/tube.off" >/dev/null
for job in "sphere.off 2 halfspace:0,1,0:0" "bunny-3k.off 1 halfspace:0,1,0:0.11" "tube.off 2 boundary"; do
  set -- $job
  [ -f "$T/$1" ] || continue
  echo "$1, order $2, --fixed $3"
  "$M" fair "$T/$1" --fixed "$3" --order "$2" --laplacian cotan -o "$T/serial-fair.ply" >/dev/null
  for n in 1 2 4; do
    "$M" partition "$T/$1" --parts $n -o "$T/fair-parts-$n" >/dev/null
    run $n "$MPI_TOOL" fair "$T/fair-parts-$n" --fixed "$3" --order "$2" -o "$T/fair-$n" --json >"$T/report.json"
    compare "$T/serial-fair.ply" "$T/fair-$n" $n positions
    joined "$T/serial-fair.ply" "$T/fair-parts-$n" "$T/fair-$n" positions
  done
done

echo "bad input"
# expect_failure WHAT PATTERN COMMAND...: non-zero, not the timeout's 124, stderr matching PATTERN.
expect_failure() {
  local what="$1" pattern="$2" rc=0
  shift 2
  "$@" >/dev/null 2>"$T/err" || rc=$?
  [ $rc -ne 0 ] || fail "$what was accepted"
  [ $rc -ne 124 ] || fail "$what: the run hung"
  grep -q -- "$pattern" "$T/err" || fail "$what: the message lacks '$pattern': $(head -5 "$T/err")"
  echo "  $what: $(grep -m1 error "$T/err")"
}
# A truncated part: the whole run fails, naming the file, within the timeout.
cp -r "$T/parts-2" "$T/broken"
head -c 300 "$T/parts-2/part-1.ply" >"$T/broken/part-1.ply"
expect_failure "a truncated part" "part-1.ply" run 2 "$MPI_TOOL" interpolate "$T/broken" --constraints "$T/cons.csv" -o "$T/x"
# A part that claims another part's vertices as its own.
cp -r "$T/parts-2" "$T/swapped"
cp "$T/parts-2/part-0.ply" "$T/swapped/part-1.ply"
expect_failure "a part holding another part's vertices" "global_id" \
  run 2 "$MPI_TOOL" interpolate "$T/swapped" --constraints "$T/cons.csv" -o "$T/x"
# A missing index, and fewer processes than parts.
expect_failure "a folder without partition.json" "partition.json" \
  run 2 "$MPI_TOOL" interpolate "$T" --constraints "$T/cons.csv" -o "$T/x"
expect_failure "4 parts on 2 processes" "mpirun -n 4" \
  run 2 "$MPI_TOOL" interpolate "$T/parts-4" --constraints "$T/cons.csv" -o "$T/x"
# A constraint on a vertex the mesh does not have, and a position instead of an index.
printf "vertex,value\n0,1\n999999999,2\n" >"$T/bad.csv"
expect_failure "a constraint out of range" "999999999 does not exist" \
  run 2 "$MPI_TOOL" interpolate "$T/parts-2" --constraints "$T/bad.csv" -o "$T/x"
# Said once for all the ranks that found it, not once a rank.
[ "$(grep -c "does not exist" "$T/err")" = 1 ] || fail "the same error printed $(grep -c "does not exist" "$T/err") times"
grep -q "ranks 0-1:" "$T/err" || fail "the error does not name the ranks: $(cat "$T/err")"
echo '{"constraints": [{"vertex": "@0,0,1", "value": 1}]}' >"$T/at.json"
expect_failure "a constraint at @X,Y,Z" "vertex indices of the input mesh" \
  run 2 "$MPI_TOOL" interpolate "$T/parts-2" --constraints "$T/at.json" -o "$T/x"
expect_failure "fair --fixed rings:0:2" "need the whole mesh" \
  run 2 "$MPI_TOOL" fair "$T/parts-2" --fixed rings:0:2 -o "$T/x"
# Intrinsic Delaunay operators need the whole surface's edge flips: refused, naming the serial tool.
expect_failure "interpolate --laplacian intrinsic" "cotangent operators only" \
  run 2 "$MPI_TOOL" interpolate "$T/parts-2" --constraints "$T/cons.csv" --laplacian intrinsic -o "$T/x"
# join: result files that do not match the partition.
expect_failure "join without result files" "found neither" "$MPI_TOOL" join "$T/parts-2" "$T/parts-2" -o "$T/x.ply"
expect_failure "join of 4 ranks' results over 2 parts" "more result files" \
  "$MPI_TOOL" join "$T/parts-2" "$T/out-4" -o "$T/x.ply"
expect_failure "join of 2 ranks' results over 4 parts" "u-2.csv: missing" \
  "$MPI_TOOL" join "$T/parts-4" "$T/out-2" -o "$T/x.ply"
cp -r "$T/out-2" "$T/badout"
sed -i '3s/,.*/,not-a-number/' "$T/badout/u-1.csv"
expect_failure "join of a malformed result" "u-1.csv: line 3: 'not-a-number' is not a number" "$MPI_TOOL" join "$T/parts-2" "$T/badout" -o "$T/x.ply"
[ ! -e "$T/x.ply" ] || fail "a failed join left $T/x.ply"
# meshpde partition's own checks.
expect_failure "--parts 0" "at least 1" "$M" partition "$T/sphere.off" --parts 0 -o "$T/p0"
expect_failure "more parts than vertices" "at most one part a vertex" "$M" partition "$T/sphere.off" --parts 100000 -o "$T/p1"
echo "distributed: all checks passed"
