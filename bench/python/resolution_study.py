#!/usr/bin/python3
"""Does a correction converge with the mesh?

The same correction on three resolutions of the same surface: a mesh (level 0), its
1-to-4 midpoint subdivision (level 1, half the edge) and its 1-to-16 (level 2). The
subdivision keeps the coarse vertices first, at the same places, so the handle is the
same vertex on every level and the displacements can be compared vertex by vertex.

For each case and region radius R (in coarse mean edges h):
  s01 = Hausdorff distance between the corrected level-0 and level-1 surfaces / |drag|
  s12 = the same between levels 1 and 2
  order = log2(s01 / s12)      (the edge halves from level to level)
s01 is "the distance from the fine result to the coarse one" of the issue's targets
(<= 1 % at R >= 5 h, <= 0.5 % at R >= 10 h). Also reported: v01 and v12, the largest
difference of the displacement at the coarse vertices (tangential slip included, so
stricter than the surface distance), and interp01: the coarse mesh's triangles through
the level-1 result's own values at the coarse vertices, against the level-1 result
(what the coarse mesh misses of the finer answer even when its vertices are exactly
right: its flat triangles cannot follow the bend in between).

    /usr/bin/python3 bench/python/resolution_study.py [--data ../shared/data]
        [--out docs/images/resolution.png] [--json out.json] [--quick]

Independent triangulations (--remeshed): each surface remeshed isotropically at three
target edge lengths h, h/2, h/4 (bench/remesh_cgal.cpp, CGAL's isotropic remeshing;
each level remeshed from the input, so no two share a vertex). The handles are surface
points, the same points in space on every level. For each rule and R (in coarse edges):
  max, rms = the coarse result's displacement at each coarse vertex near the handles
             (within 1.2 R) against the finer result's at the same surface point (its
             closest point, interpolated), / drag, for the pairs (h, h/2) and (h/2, h/4)
  order    = log2 of their ratio
  haus     = Hausdorff distance between the corrected (h/2, h/4) surfaces / drag, beside
  floor    = the same between the two uncorrected remeshed surfaces (what remeshing
             itself changes: the comparison cannot go below it)
Rules: "point smooth" (a handle point, the smooth boundary: the default), "vertex clamp"
(the nearest vertex, edge-path region clamped at R - h: the rule before) and "springs"
(the thesis's, the nearest vertex, R in rings).

    /usr/bin/python3 bench/python/resolution_study.py --remeshed
        [--remesher build/release/bench/meshpde_remesh] [--json out.json] [--out plot.png]

Needs the meshpde Python module (PYTHONPATH=build/release/python) and matplotlib.
"""
import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

import meshpde


def levels(V, F, n=3):
    out = [(np.asarray(V, float), np.asarray(F, np.int64))]
    for _ in range(n - 1):
        V1, F1 = meshpde.generate.subdivide(*out[-1])
        assert np.array_equal(V1[: len(out[-1][0])], out[-1][0]), "subdivision moved a coarse vertex"
        out.append((V1, F1))
    return out


def mean_edge(V, F):
    e = np.concatenate([V[F[:, 0]] - V[F[:, 1]], V[F[:, 1]] - V[F[:, 2]], V[F[:, 2]] - V[F[:, 0]]])
    return float(np.linalg.norm(e, axis=1).mean())


def nearest(V, p):
    return int(np.argmin(np.linalg.norm(V - np.asarray(p), axis=1)))


def trunk_handle(path):
    """An aorta's three levels and its handle: the vertex nearest the point 70 % along
    the bounding box's longest side, moved 3 mm inwards along its outward normal."""
    V, F, _ = meshpde.read_mesh(path)
    N = meshpde.vertex_normals(V, F, outward=True)
    lo, hi = V.min(0), V.max(0)
    long_axis = int(np.argmax(hi - lo))
    p = (lo + hi) / 2
    p[long_axis] = lo[long_axis] + 0.7 * (hi[long_axis] - lo[long_axis])
    v = nearest(V, p)
    return levels(V, F), [(v, -3.0 * N[v])]


def cases(data, quick):
    """(name, levels, handles: [(vertex, move)], image or None, space)"""
    out = []
    # A generated tube, radius 5 mm, edges about 1.1 mm, long enough that no region
    # reaches its open ends: a handle half way along, 3 mm in.
    V, F = meshpde.generate.tube(radius=5.0, length=100.0, rings=88, segments=32)
    L = levels(V, F)
    axis = int(np.argmax(V.max(0) - V.min(0)))
    mid = V.mean(0)
    ring = np.abs(V[:, axis] - mid[axis]) < 0.6
    v = int(np.flatnonzero(ring)[0])
    n = meshpde.vertex_normals(V, F)[v]
    out.append((f"tube r=5 ({len(V) / 1000:.1f}k)", L, [(v, -3.0 * n)], None, "lps"))
    if quick:
        return out
    # The same tube remeshed, not subdivided: 32, 64 and 128 segments around, rings to
    # match, so no vertex is shared. The handle is the vertex nearest one wall point,
    # moved to the point 3 mm inside it at every level.
    L = []
    for seg in (32, 64, 128):
        h = 2 * math.pi * 5.0 / seg
        L.append(tuple(np.asarray(x) for x in meshpde.generate.tube(radius=5.0, length=100.0,
                                                                     rings=int(round(100.0 / h)), segments=seg)))
    zmid = float(L[0][0][:, 2].min() + L[0][0][:, 2].max()) / 2
    wall, target = np.array([5.0, 0.0, zmid]), np.array([2.0, 0.0, zmid])

    def remeshed_handles(V):
        v = nearest(V, wall)
        return [(v, target - V[v])]
    out.append(("tube r=5, remeshed 32/64/128", L, remeshed_handles, None, "lps"))
    # The generated bifurcation: a handle on the trunk, and two handles.
    V, F = meshpde.generate.bifurcation(cell=1.0)
    L = levels(V, F)
    N = meshpde.vertex_normals(V, F)
    c = V.mean(0)
    top = V[:, 2].max()
    v = nearest(V, [c[0] + 4.0, c[1], top - 0.35 * (top - V[:, 2].min())])
    out.append(("bifurcation (cell 1 mm)", L, [(v, -3.0 * N[v])], None, "lps"))
    w = nearest(V, V[v] + np.array([0.0, 0.0, -12.0]))
    out.append(("bifurcation, two handles", L, [(v, -3.0 * N[v]), (w, 2.0 * N[w])], None, "lps"))
    # The real aorta (RAS mm, inward oriented), closed and with its ends cut open: a
    # trunk vertex 3 mm in; the closed one also with the MRA's guidance.
    for name, label in (("aorta-closed-6k.vtp", "aorta-closed-6k"), ("aorta-open-6k.stl", "aorta-open-6k (open ends)")):
        mesh = Path(data) / name
        if not mesh.exists():
            print(f"note: {mesh} not found: its rows are left out", file=sys.stderr)
            continue
        L, handles = trunk_handle(mesh)
        out.append((label, L, handles, None, "ras"))
        mra = Path(data) / "aorta-mra.mha"
        if name.startswith("aorta-closed") and mra.exists():
            out.append((f"{label}, MRA guidance", L, handles, str(mra), "ras"))
    return out


def run_case(name, L, handles, image, space, R, method, boundary="clamp"):
    """handles: [(vertex, move)] for nested levels (subdivisions), or a function of a
    level's V giving them (remeshed levels, whose vertices differ)."""
    nested = not callable(handles)
    per_level = [handles if nested else handles(V) for V, _ in L]
    h = mean_edge(*L[0])
    drag = max(np.linalg.norm(m) for _, m in per_level[0])
    ds = []
    for (V, F), handles in zip(L, per_level):
        kw = dict(method=method, allow_intersections=True)
        if method == "springs":
            kw["rings"] = max(1, round(R))  # rings of the coarse mesh: the thesis's level of influence
            if len(ds) > 0:  # the same reach in mm on the finer mesh: twice, four times the rings
                kw["rings"] = max(1, round(R * h / mean_edge(V, F)))
        else:
            kw["radius"] = R * h
            kw["boundary"] = boundary
        if image:
            kw.update(image=image, space=space)
        r = meshpde.correct(V, F, [v for v, _ in handles], [list(m) for _, m in handles], **kw)
        ds.append(np.asarray(r.displacement))
    n0 = len(L[0][0])
    moved = [(V + d, F) for (V, F), d in zip(L, ds)]
    s01 = meshpde.hausdorff_distance(*moved[0], *moved[1]) / drag
    s12 = meshpde.hausdorff_distance(*moved[1], *moved[2]) / drag
    v01 = v12 = interp01 = None  # defined where the levels share the coarse vertices
    if nested:
        v01 = float(np.linalg.norm(ds[1][:n0] - ds[0][:n0], axis=1).max() / drag)
        v12 = float(np.linalg.norm(ds[2][:n0] - ds[1][:n0], axis=1).max() / drag)
        # What the coarse mesh's triangles miss of the fine result even through its own
        # values: the coarse triangles through the level-1 displacement at the coarse
        # vertices, against the level-1 result (the interpolation error).
        interp01 = meshpde.hausdorff_distance(L[0][0] + ds[1][:n0], L[0][1], *moved[1]) / drag
    return {"case": name, "method": method if method == "springs" else f"fem {boundary}", "R_over_h": R, "R_mm": R * h, "h_mm": h, "drag_mm": drag,
            "s01": s01, "s12": s12, "order": math.log2(s01 / s12) if s12 > 0 and s01 > 0 else None,
            "v01": v01, "v12": v12, "interp01": interp01, "vertices": [len(V) for V, _ in L]}


def remesh(remesher, V, F, edge, seed, workdir):
    """One isotropic remeshing of (V, F) to `edge` (bench/remesh_cgal.cpp)."""
    import subprocess
    src, dst = workdir / f"in{seed}.obj", workdir / f"out{seed}.obj"
    meshpde.write_mesh(str(src), V, F)
    subprocess.run([remesher, str(src), str(dst), "--edge", repr(edge), "--seed", str(seed)], check=True,
                   stdout=subprocess.DEVNULL)
    V1, F1, _ = meshpde.read_mesh(str(dst))
    return np.asarray(V1, float), np.asarray(F1, np.int64)


def remeshed_cases(data, remesher, quick):
    """(name, [(V, F)] at h, h/2, h/4, handles: [(point, move)], image or None, space)"""
    import tempfile
    work = Path(tempfile.mkdtemp())
    inputs = []
    V, F = meshpde.generate.tube(radius=5.0, length=100.0, rings=88, segments=32)
    V, F = np.asarray(V, float), np.asarray(F, np.int64)
    # The handle at a wall point that is no vertex of any level (a point on a vertex reads
    # the same whatever the reading; the remesher happens to keep (5, 0, zmid) a vertex).
    zmid, a = float(V[:, 2].mean()), 0.37
    radial = np.array([math.cos(a), math.sin(a), 0.0])
    inputs.append(("tube r=5", V, F, [(5.0 * radial + [0.0, 0.0, zmid + 0.41], -3.0 * radial)], None, "lps"))
    if not quick:
        V, F = meshpde.generate.bifurcation(cell=0.8)
        V, F = np.asarray(V, float), np.asarray(F, np.int64)
        N = meshpde.vertex_normals(V, F, outward=True)
        c, top = V.mean(0), V[:, 2].max()
        v = nearest(V, [c[0] + 4.0, c[1], top - 0.35 * (top - V[:, 2].min())])
        w = nearest(V, V[v] + np.array([0.0, 0.0, -12.0]))
        inputs.append(("bifurcation", V, F, [(V[v], -3.0 * N[v])], None, "lps"))
        inputs.append(("bifurcation, two handles", V, F, [(V[v], -3.0 * N[v]), (V[w], 2.0 * N[w])], None, "lps"))
        for name in ("aorta-closed-6k.vtp", "aorta-open-6k.stl"):
            path = Path(data) / name
            if not path.exists():
                print(f"note: {path} not found: its rows are left out", file=sys.stderr)
                continue
            V, F, _ = meshpde.read_mesh(str(path))
            V, F = np.asarray(V, float), np.asarray(F, np.int64)
            N = meshpde.vertex_normals(V, F, outward=True)
            lo, hi = V.min(0), V.max(0)
            axis = int(np.argmax(hi - lo))
            p = (lo + hi) / 2
            p[axis] = lo[axis] + 0.7 * (hi[axis] - lo[axis])
            v = nearest(V, p)
            label = name.split(".")[0]
            inputs.append((label, V, F, [(V[v], -3.0 * N[v])], None, "ras"))
            mra = Path(data) / "aorta-mra.mha"
            if name.startswith("aorta-closed") and mra.exists():
                inputs.append((f"{label}, MRA guidance", V, F, [(V[v], -3.0 * N[v])], str(mra), "ras"))
    out, cache = [], {}
    for name, V, F, handles, image, space in inputs:
        key = name.split(",")[0]
        if key not in cache:
            h = mean_edge(V, F)
            cache[key] = [remesh(remesher, V, F, h / 2 ** k, k + 1, work) for k in range(3)]
        out.append((name, cache[key], handles, image, space))
    return out


def at_points(V, F, d, P):
    """The field d (per vertex of (V, F)) at the surface points nearest to P."""
    faces, bary = meshpde.closest_surface_points(V, F, P)
    return (bary[:, :, None] * d[F[faces]]).sum(1)


def run_remeshed(name, L, handles, image, space, R, rule):
    h = mean_edge(*L[0])
    drag = max(np.linalg.norm(m) for _, m in handles)
    points = np.array([p for p, _ in handles])
    ds = []
    for V, F in L:
        kw = dict(allow_intersections=True)
        if image:
            kw.update(image=image, space=space)
        if rule == "point smooth":
            r = meshpde.correct(V, F, points=points, moves=[list(m) for _, m in handles], radius=R * h, **kw)
        else:
            verts = [nearest(V, p) for p, _ in handles]
            if rule == "springs":
                kw.update(method="springs", rings=max(1, round(R * h / mean_edge(V, F))))
            else:
                kw.update(radius=R * h, boundary="clamp")
            r = meshpde.correct(V, F, verts, [list(m) for _, m in handles], **kw)
        ds.append(np.asarray(r.displacement))
    mx, rms = [], []
    for k in range(2):
        V, F = L[k]
        near = np.min(np.linalg.norm(V[:, None, :] - points[None, :, :], axis=2), axis=1) < 1.2 * R * h
        e = np.linalg.norm(ds[k][near] - at_points(*L[k + 1], ds[k + 1], V[near]), axis=1) / drag
        mx.append(float(e.max()))
        rms.append(float(np.sqrt((e ** 2).mean())))
    moved = [(V + d, F) for (V, F), d in zip(L, ds)]
    haus = meshpde.hausdorff_distance(*moved[1], *moved[2]) / drag
    floor = meshpde.hausdorff_distance(*L[1], *L[2]) / drag
    order = lambda a: math.log2(a[0] / a[1]) if a[1] > 0 and a[0] > 0 else None
    return {"case": name, "method": rule, "R_over_h": R, "R_mm": R * h, "h_mm": h, "drag_mm": drag,
            "max01": mx[0], "max12": mx[1], "max_order": order(mx), "rms01": rms[0], "rms12": rms[1],
            "rms_order": order(rms), "hausdorff12": haus, "floor12": floor, "vertices": [len(V) for V, _ in L]}


def main_remeshed(a):
    rows = []
    t0 = time.time()
    for name, L, handles, image, space in remeshed_cases(a.data, a.remesher, a.quick):
        for rule in ("point smooth", "vertex clamp", "springs"):
            if image and rule == "springs":
                continue
            for R in (5, 10, 20):
                r = run_remeshed(name, L, handles, image, space, R, rule)
                rows.append(r)
                pct = lambda x: f"{100 * x:6.2f} %"
                o = lambda x: f"{x:5.2f}" if x is not None else "  -  "
                print(f"{name:28s} {rule:13s} R = {R:2d} h ({r['R_mm']:5.1f} mm): max {pct(r['max01'])} -> "
                      f"{pct(r['max12'])} (order {o(r['max_order'])})  rms {pct(r['rms01'])} -> {pct(r['rms12'])} "
                      f"(order {o(r['rms_order'])})  hausdorff {pct(r['hausdorff12'])}, floor {pct(r['floor12'])}",
                      flush=True)
    print(f"({time.time() - t0:.0f} s; vertices per level: " +
          ", ".join(f"{r['case']} {r['vertices']}" for r in rows if r['R_over_h'] == 5 and r['method'] == 'springs') +
          ")")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    if a.out:
        plot_pairs(rows, ("point smooth", "vertex clamp", "springs"), "max01", "max12",
                   "coarse vs finer at the same point", "largest difference / drag (%)", a.out)


def plot_pairs(rows, methods, coarse_key, fine_key, what, ylabel, out):
    """One panel per method: each case's difference between the coarse pair (h, h/2)
    and the finer pair (h/2, h/4) of its resolutions, plotted at the finer edge of
    each pair, with 1 % and 0.5 % marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    fig, axes = plt.subplots(1, len(methods), figsize=(15, 4.4), sharey=True)
    names = list(dict.fromkeys(r["case"] for r in rows))
    colour = {n: f"C{k}" for k, n in enumerate(names)}
    marker = {5: "o", 10: "s", 20: "^"}
    for ax, method in zip(axes, methods):
        for r in rows:
            if r["method"] == method:
                h = r["h_mm"]
                ax.loglog([h / 2, h / 4], [100 * r[coarse_key], 100 * r[fine_key]], "-", color=colour[r["case"]],
                          marker=marker[r["R_over_h"]])
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.axhline(0.5, color="k", lw=0.8, ls=":")
        ax.set_title(f"{method}: {what}")
        ax.set_xlabel("finer mean edge of the pair (mm)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(ylabel)
    handles = [Line2D([], [], color=colour[n], label=n) for n in names]
    handles += [Line2D([], [], color="grey", marker=m, ls="", label=f"R = {R} h") for R, m in marker.items()]
    handles += [Line2D([], [], color="k", ls="--", label="1 %"), Line2D([], [], color="k", ls=":", label="0.5 %")]
    axes[-1].legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1))
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"plot {out}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[3] / "shared" / "data"))
    ap.add_argument("--out", default="", help="PNG of the error against h")
    ap.add_argument("--json", default="", help="the table as JSON")
    ap.add_argument("--quick", action="store_true", help="the tube only")
    ap.add_argument("--remeshed", action="store_true",
                    help="independent triangulations (isotropic remeshing at h, h/2, h/4) instead of subdivisions")
    ap.add_argument("--remesher", default=str(Path(__file__).resolve().parents[2] / "build" / "release" / "bench" /
                                              "meshpde_remesh"), help="the meshpde_remesh binary (needs CGAL)")
    a = ap.parse_args()
    if a.remeshed:
        main_remeshed(a)
        return
    rows = []
    t0 = time.time()
    for name, L, handles, image, space in cases(a.data, a.quick):
        for method, boundary in (("fem", "clamp"), ("fem", "fade"), ("springs", "")):
            if image and method == "springs":
                continue  # the springs' image step is its own, not the FEM's
            for R in (5, 10, 20):
                r = run_case(name, L, handles, image, space, R, method, boundary)
                rows.append(r)
                order = f"{r['order']:.2f}" if r["order"] is not None else "-"
                pct = lambda x: f"{100 * x:6.2f} %" if x is not None else "     -  "
                print(f"{name:32s} {r['method']:10s} R = {R:2d} h ({r['R_mm']:5.1f} mm): "
                      f"s01 {pct(r['s01'])}  s12 {pct(r['s12'])}  order {order}   "
                      f"(vertices: v01 {pct(r['v01'])}  v12 {pct(r['v12'])}; "
                      f"interpolation {pct(r['interp01'])})", flush=True)
    print(f"({time.time() - t0:.0f} s)")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    if a.out:
        plot_pairs(rows, ("fem clamp", "fem fade", "springs"), "s01", "s12", "change from one level to the next",
                   "Hausdorff distance between the results / drag (%)", a.out)


if __name__ == "__main__":
    main()
