"""Never a NaN: seeded random meshes with zero-area triangles,
repeated vertices, needles and caps, through every command of the tool. Each run either
succeeds with finite output (the written mesh, its fields and the JSON report) or exits
1 with a message that names the offending element; never a crash, a hang or a NaN."""
import json
import math
import os
import re
import subprocess

import numpy as np
import pytest

import meshpde

SEEDS = range(int(os.environ.get("MESHPDE_DEGENERATE_SEEDS", "4")))  # even: tubes, odd: spheres
DEFECTS = ("zero_area", "repeated_vertex", "needle", "cap", "all")

# An error message names an element: "vertex 12", "triangle 7", "face 3", "edge (4, 9)" ...
NAMES_ELEMENT = re.compile(r"\b(vertex|vertices|triangle|triangles|face|faces|edge|edges|point|corner)\b\s*[\d(]",
                           re.IGNORECASE)


def degenerate_mesh(seed, defect):
    """A jittered tube or sphere with a few of one defect (or all of them) planted."""
    rng = np.random.default_rng(seed)
    if seed % 2:
        V, F = meshpde.generate.icosphere(3)
    else:
        V, F = meshpde.generate.tube(radius=1.0, length=4.0, segments=24, rings=20)
    V = V + rng.normal(scale=0.01, size=V.shape)
    F = F.copy()
    kinds = DEFECTS[:4] if defect == "all" else (defect,)
    for kind in kinds:
        for t in rng.choice(len(F), size=3, replace=False):
            a, b, c = F[t]
            if kind == "zero_area":  # c onto the middle of a-b: the triangle is flat
                V[c] = 0.5 * (V[a] + V[b])
            elif kind == "repeated_vertex":  # a second vertex at the same place
                V[b] = V[a]
            elif kind == "needle":  # one edge 1e-12 long
                V[b] = V[a] + 1e-12
            elif kind == "cap":  # c just off the line a-b, between them: an angle near 180 degrees
                V[c] = 0.3 * V[a] + 0.7 * V[b] + 1e-9 * rng.normal(size=3)
    return V, F


def finite_json(value, where="report"):
    if isinstance(value, float):
        assert math.isfinite(value), f"{where} is {value}"
    elif isinstance(value, dict):
        for k, v in value.items():
            finite_json(v, f"{where}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            finite_json(v, f"{where}[{i}]")


def commands(mesh, out, tmp, V):
    """Every command of the tool on `mesh`, with a handle and sources in its middle."""
    handle = int(np.argmin(np.linalg.norm(V - V.mean(axis=0), axis=1)))
    csv = tmp / "constraints.csv"
    csv.write_text(f"{handle},1\n{(handle + 7) % len(V)},-1\n{(handle + 31) % len(V)},0.5\n")
    small = ["--size", "64x48"]
    return {
        "info": ["info", mesh, "--json"],
        "curvature": ["curvature", mesh, "-o", out, "--json"],
        "correct": ["correct", mesh, "--vertex", handle, "--move", "normal:0.2", "--rings", 4, "-o", out, "--json"],
        "correct_springs": ["correct", mesh, "--vertex", handle, "--move", "0.1,0,0", "--rings", 3, "--method",
                            "springs", "-o", out, "--json"],
        "interpolate": ["interpolate", mesh, "--constraints", csv, "-o", out, "--json"],
        "heat": ["heat", mesh, "--source", f"{handle}:1", "--steps", 5, "-o", out, "--json"],
        "heat_local": ["heat", mesh, "--source", f"{handle}:1", "--steps", 5, "--local", "-o", out, "--json"],
        "wave": ["wave", mesh, "--impulse", f"{handle}:1", "--steps", 5, "-o", out, "--json"],
        "fair": ["fair", mesh, "--fixed", f"radius:{handle}:0.5", "--order", 2, "-o", out, "--json"],
        # The default press at a 250 Hz servo: the same path and the same domain growth
        # (its largest free set equals the 1 kHz run's to a vertex or two) in a quarter
        # of the steps and factors.
        "poke": ["poke", mesh, "--vertex", handle, "--no-realtime", "--settle", 0.05, "--rate", 250, "--json"],
        "convert": ["convert", mesh, out],
        "render": ["render", mesh, "-o", tmp / "picture.png", *small],
    }


@pytest.mark.parametrize("defect", DEFECTS)
def test_every_command_succeeds_finitely_or_names_the_element(tmp_path, cli_path, defect):
    failures = []
    for seed in SEEDS:
        V, F = degenerate_mesh(seed, defect)
        mesh = tmp_path / f"{defect}-{seed}.obj"
        meshpde.write_mesh(mesh, V, F)
        for name, args in commands(mesh, tmp_path / "out.ply", tmp_path, V).items():
            out = tmp_path / "out.ply"
            out.unlink(missing_ok=True)
            run = subprocess.run([cli_path, *map(str, args)], capture_output=True, text=True, timeout=120)
            what = f"seed {seed} {name}: meshpde {' '.join(map(str, args))}"
            if run.returncode == 1:
                if not NAMES_ELEMENT.search(run.stderr):
                    failures.append(f"{what}: exit 1 without naming an element: {run.stderr.strip()[:300]}")
                continue
            if run.returncode != 0:
                failures.append(f"{what}: exit {run.returncode}: {run.stderr.strip()[-300:]}")
                continue
            if "--json" in args:
                finite_json(json.loads(run.stdout), what)
            if out.exists():
                V2, F2, fields = meshpde.read_mesh(out)
                if not np.isfinite(V2).all():
                    failures.append(f"{what}: non-finite vertex in the output")
                for key, value in fields.items():
                    if not np.isfinite(value).all():
                        failures.append(f"{what}: non-finite field '{key}' in the output")
    assert not failures, "\n".join(failures)
