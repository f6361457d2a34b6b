#!/usr/bin/env bash
# Runs the CGAL peer benchmark on a small icosphere and checks that the peers' answers
# agree where they solve the same problem: the membrane fairings (the same cotangent
# Laplacian) to rounding, the thin-plate fairings to 5 % of the move (CGAL weights
# its bi-Laplacian by Voronoi areas, meshpde by barycentric ones), Eigen's simplicial
# solve of meshpde's system to rounding, and the drag's handle in both deformations.
set -euo pipefail
out="$(mktemp)"
trap 'rm -f "$out"' EXIT
"$1" --level 4 --json >"$out"
python3 - "$out" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
o1, o2 = d["fair_order1"], d["fair_order2"]
checks = {
    "membrane fairing equals CGAL's (Hausdorff < 1e-9)": o1["hausdorff_to_cgal"] < 1e-9,
    "thin-plate fairing within 5 % of the move of CGAL's": o2["hausdorff_to_cgal"] < 0.05 * o2["largest_fairing_move"],
    "fairing moved something": o2["largest_fairing_move"] > 0.1,
    "Eigen's simplicial solve equals meshpde's": max(o1["max_difference_to_eigen"], o2["max_difference_to_eigen"]) < 1e-9,
    "meshpde's handle lands": d["meshpde_drag"]["handle_miss"] < 1e-9,
    "CGAL's handle lands": d["cgal_drag_spokes_and_rims"]["handle_miss"] < 1e-6,
    "timings are positive": min(o1["meshpde_s"], o1["cgal_s"], d["cgal_fair_c2_s"]) > 0,
}
failed = [k for k, ok in checks.items() if not ok]
for k in checks:
    print(("FAIL: " if k in failed else "ok: ") + k)
if failed:
    print(json.dumps(d, indent=1))
    sys.exit(1)
PY
