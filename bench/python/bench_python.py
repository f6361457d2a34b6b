#!/usr/bin/python3
"""The Python module's overheads, each beside its C++ baseline from the same run.

    PYTHONPATH=build/release/python /usr/bin/python3 bench/python/bench_python.py [--quick] [--json]

python_poke_step_overhead_us: the median per-step time of a PdeSession poke driven
from Python (constrain + step per step, as `meshpde bench`'s poke: 10k-vertex
icosphere of unit mean edge, bi-Laplacian plate on a foundation, self-adjusting
domain, 1,000 steps of 1 ms, the vertex pushed in half an edge and out again) minus
the median of the same loop run in C++ on a fresh session (target <= 20 us).
Rounds alternate Python and C++ loops; the figure is the median over rounds.

python_stiffness_s_655k: meshpde.stiffness(V, F) on the 655k icosphere (argument
checks, connectivity, operators, scipy.sparse.csr_matrix) against the C++ time of
Mesh + build_cotan_operators + stiffness_matrix on the same arrays (target <= 1.3x); best
of five each, interleaved (the first calls of a process pay for fresh pages).
"""
import argparse
import json
import statistics
import time

import numpy as np

import meshpde
from meshpde import _meshpde


def unit_edge_icosphere(level):
    V, F = meshpde.generate.icosphere(level)
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    return V / np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean(), F


def poke_session(V, F):
    return meshpde.PdeSession(V, F, components=3, alpha=1.0, b1=1.0, b2=0.01, g0=1.0, g1=0.0, g2=100.0,
                              self_adjusting=True, rest_value=1e-4, rest_rate=1e-3, tolerance=1e-6,
                              max_iterations=200)


def python_poke(V, F, handle, n, steps):
    s = poke_session(V, F)
    us = []
    clock = time.perf_counter_ns
    for k in range(steps):
        target = -0.5 * np.sin(np.pi * (k + 1) / steps) * n
        t = clock()
        s.constrain(handle, target)
        s.step(1e-3)
        us.append((clock() - t) / 1e3)
    return us


def cpp_poke(V, F, handle, n, steps):
    return _meshpde._bench.poke_step_us(poke_session(V, F), handle, -n, 0.5, steps, 1e-3)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer rounds and steps")
    ap.add_argument("--json", action="store_true", help="print a JSON object")
    a = ap.parse_args()
    rounds, steps = (2, 300) if a.quick else (5, 1000)

    V, F = unit_edge_icosphere(5)
    handle = int(np.argmax(V[:, 2]))
    n = V[handle] / np.linalg.norm(V[handle])
    py_p50, cpp_p50 = [], []
    for _ in range(rounds):
        py_p50.append(statistics.median(python_poke(V, F, handle, n, steps)))
        cpp_p50.append(statistics.median(cpp_poke(V, F, handle, n, steps)))
    overheads = [p - c for p, c in zip(py_p50, cpp_p50)]

    V8, F8 = meshpde.generate.icosphere(6 if a.quick else 8)
    tag = "41k" if a.quick else "655k"
    py_s, cpp_s = [], []
    for _ in range(5):
        t = time.perf_counter()
        K = meshpde.stiffness(V8, F8)
        py_s.append(time.perf_counter() - t)
        cpp_s.append(_meshpde._bench.stiffness_seconds(V8, F8))
    assert K.shape == (len(V8), len(V8))

    out = {
        "python_poke_step_overhead_us": statistics.median(overheads),
        "python_poke_step_p50_us": statistics.median(py_p50),
        "python_poke_step_cpp_baseline_p50_us": statistics.median(cpp_p50),
        "python_poke_step_overhead_us_per_round": overheads,
        "python_poke_steps": steps,
        f"python_stiffness_s_{tag}": min(py_s),
        f"python_stiffness_cpp_baseline_s_{tag}": min(cpp_s),
        f"python_stiffness_ratio_{tag}": min(py_s) / min(cpp_s),
    }
    if a.json:
        print(json.dumps(out, indent=2))
    else:
        for k, v in out.items():
            print(f"{k}: {v if not isinstance(v, float) else round(v, 4)}")


if __name__ == "__main__":
    main()
