#!/usr/bin/python3
"""Which distance on the surface should a region of influence use? The three candidates
against analytic distances, at three resolutions each:

  unfolding  meshpde.geodesic_distance (mesh/geodesic_distance.h: fast marching's exact
             point-source update in Dijkstra's order, with sweeps) - what corrections use
  heat       the heat method (Crane, Weischedel and Wardetzky, "Geodesics in Heat", 2013)
             built on meshpde's own operators: (M + t K) u = delta at the source,
             X = -grad u / |grad u| per triangle, K phi = div X, t = h^2 (h the mean edge)
  edges      Dijkstra along the edges (mesh/regions.h's geodesic_distances)

Surfaces: the unit sphere (icospheres, levels 3, 4, 5; great-circle distance from a
vertex, compared within distance 1) and a cylinder of radius 1 (tubes of 32, 64 and 128
segments; the unrolled straight line from a vertex half way along, compared within 2,
away from the open ends). Reported: the largest error over the vertices compared, in
units of the mean edge h and absolute, and the order from one level to the next.

    PYTHONPATH=build/release/python /usr/bin/python3 bench/python/geodesic_study.py

Needs the meshpde Python module and scipy.
"""
import math
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import meshpde


def mean_edge(V, F):
    e = np.concatenate([V[F[:, 0]] - V[F[:, 1]], V[F[:, 1]] - V[F[:, 2]], V[F[:, 2]] - V[F[:, 0]]])
    return float(np.linalg.norm(e, axis=1).mean())


def heat_method(V, F, source):
    """Geodesics in Heat with meshpde's stiffness K (positive semi-definite) and lumped mass M."""
    K = meshpde.stiffness(V, F).tocsc()
    M = meshpde.mass(V, F).tocsc()
    t = mean_edge(V, F) ** 2
    delta = np.zeros(len(V))
    delta[source] = 1.0
    u = spla.spsolve((M + t * K).tocsc(), delta)
    # Per triangle: grad u = sum_k u_k grad(phi_k), grad(phi_k) = n x e_k / (2 A), e_k the
    # edge opposite corner k (oriented along the triangle).
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    n = n / area2[:, None]
    edges = [c - b, a - c, b - a]
    grads = [np.cross(n, e) / area2[:, None] for e in edges]  # grad(phi_k)
    g = sum(u[F[:, k]][:, None] * grads[k] for k in range(3))
    X = -g / np.maximum(np.linalg.norm(g, axis=1), 1e-300)[:, None]
    # Laplace phi = div X, weakly: -(K phi)_i = integral of (div X) phi_i = -sum over the
    # triangles at i of A (X . grad(phi_i)), so K phi = b with b_i that sum; phi shifted
    # to 0 at the source.
    area = 0.5 * area2
    div = np.zeros(len(V))
    for k in range(3):
        np.add.at(div, F[:, k], area * np.einsum("ij,ij->i", X, grads[k]))
    # K is singular (constants): pin the source.
    keep = np.arange(len(V)) != source
    phi = np.zeros(len(V))
    phi[keep] = spla.spsolve(K[keep][:, keep].tocsc(), div[keep])
    return phi - phi[source]


def edge_paths(V, F, source):
    n = len(V)
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    w = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    G = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([E[:, 0], E[:, 1]]), np.concatenate([E[:, 1], E[:, 0]]))),
                      shape=(n, n)).tocsr()
    from scipy.sparse.csgraph import dijkstra
    return dijkstra(G, indices=source)


def families():
    out = []
    for level in (3, 4, 5):
        V, F = meshpde.generate.icosphere(level=level)
        V, F = np.asarray(V, float), np.asarray(F, np.int64)
        exact = np.arccos(np.clip(V @ V[0], -1, 1))
        out.append(("sphere", f"icosphere {level}", V, F, 0, exact, exact <= 1.0))
    for seg in (32, 64, 128):
        h = 2 * math.pi / seg
        V, F = meshpde.generate.tube(radius=1.0, length=6.0, rings=int(round(6.0 / h)) + 1, segments=seg)
        V, F = np.asarray(V, float), np.asarray(F, np.int64)
        s = int(np.argmin(np.abs(V[:, 2] - 3.0) + np.abs(np.arctan2(V[:, 1], V[:, 0]))))
        dtheta = np.remainder(np.arctan2(V[:, 1], V[:, 0]) - np.arctan2(V[s, 1], V[s, 0]) + math.pi, 2 * math.pi) - math.pi
        exact = np.hypot(dtheta, V[:, 2] - V[s, 2])
        out.append(("cylinder", f"tube {seg} segments", V, F, s, exact, exact <= 2.0))
    return out


def main():
    rows = {}
    for surface, name, V, F, s, exact, compare in families():
        h = mean_edge(V, F)
        t0 = time.time()
        unfold = meshpde.geodesic_distance(V, F, s)
        t_unfold = time.time() - t0
        t0 = time.time()
        heat = heat_method(V, F, s)
        t_heat = time.time() - t0
        edges = edge_paths(V, F, s)
        for method, d, secs in (("unfolding", unfold, t_unfold), ("heat", heat, t_heat), ("edges", edges, None)):
            err = float(np.abs(d[compare] - exact[compare]).max())
            rows.setdefault((surface, method), []).append((name, len(V), h, err, secs))
    for (surface, method), levels in rows.items():
        print(f"{surface:8s} {method:9s}", end="")
        for k, (name, n, h, err, secs) in enumerate(levels):
            order = f", order {math.log(levels[k - 1][3] / err) / math.log(levels[k - 1][2] / h):.2f}" if k else ""
            t = f", {1000 * secs:.0f} ms" if secs is not None else ""
            print(f" | {n} vertices: {err:.2e} ({err / h:.3f} h){order}{t}", end="")
        print()


if __name__ == "__main__":
    main()
