#!/usr/bin/python3
"""Draws docs/images/architecture.png: meshpde's layers and components (docs/architecture.md).

Usage: /usr/bin/python3 scripts/architecture-figure.py [OUT.png]
"""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

# (row from the bottom, x, width, title, contents, colour): the core library's layers
# on the left, each calling only those below it; the optional components on the right.
CORE = "#dbe7f5"
OPTIONAL = "#f6e3c8"
FRONT = "#dcefdc"
BOXES = [
    (0, 0.0, 6.4, "core/", "errors (InputError, SolverError), thread limits", CORE),
    (1, 0.0, 4.2, "mesh/", "Mesh, Field, topology, regions, surface distance,\ncaps, units, self-intersections, generators",
     CORE),
    (1, 4.4, 2.0, "io/, image/", "OBJ, OFF, PLY, STL, the format\nregistry; volumes, slices", CORE),
    (2, 0.0, 6.4, "operators/", "K, M, D, K D K; cotangent and intrinsic Delaunay; curvature, connection", CORE),
    (3, 0.0, 6.4, "solvers/", "conjugate gradients, sparse Cholesky (CHOLMOD), surface multigrid, orderings", CORE),
    (4, 0.0, 6.4, "pde/", "PdeSession (stepping, constraints, self-adjusting domain), steady solves,\nglobal bi-Laplacian",
     CORE),
    (5, 0.0, 6.4, "apps/",
     "vessel correction (src/apps/correction/, a file a topic), drag, interpolation,\n"
     "fairing, heat and wave, haptics, segment surfaces",
     CORE),
    (6, 0.0, 2.0, "cli/", "meshpde, meshpde-mpi;\nserve starts the editor", FRONT),
    (6, 2.2, 2.0, "python/", "the meshpde module\n(pybind11), meshpde.batch", FRONT),
    (6, 4.4, 2.0, "web/", "the editor page\n(three.js)", FRONT),
    (1.5, 7.0, 3.0, "meshpde::medical", "src/medical/: .vtp/.vtk (VTK), MetaImage, NIfTI,\nNRRD, DICOM (GDCM), segmentations",
     OPTIONAL),
    (3.0, 7.0, 3.0, "meshpde::viz", "viz/: the headless renderer (PNG)", OPTIONAL),
    (4.5, 7.0, 3.0, "meshpde::distributed", "distributed/: partitions, solves\nover MPI (PETSc)", OPTIONAL),
    (0.0, 7.0, 3.0, "meshpde::editor", "editor/: a page's session and protocol,\nthe server (websocketpp)", OPTIONAL),
]


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "docs/images/architecture.png"
    fig, ax = plt.subplots(figsize=(10.5, 6.4), dpi=110)
    h = 0.78
    for row, x, w, title, text, colour in BOXES:
        y = row
        ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.02,rounding_size=0.08", fc=colour,
                                    ec="#44546a", lw=1.0))
        ax.text(x + 0.1, y + h - 0.12, title, fontsize=10, fontweight="bold", va="top", family="monospace")
        ax.text(x + 0.1, y + h - 0.38, text, fontsize=8, va="top")
    # Calls run downwards: each layer uses those below it.
    ax.add_patch(FancyArrowPatch((6.65, 6.4), (6.65, 0.3), arrowstyle="-|>", mutation_scale=14, color="#44546a"))
    ax.text(6.78, 3.4, "calls", rotation=90, va="center", fontsize=8, color="#44546a")
    ax.text(7.0, 6.15, "optional components\n(CMake targets, each\nwith its heavy dependency)", fontsize=8, va="top",
            color="#44546a")
    ax.text(0.0, 7.0, "meshpde::meshpde (the core library)  and the front ends above it", fontsize=9, color="#44546a")
    ax.set_xlim(-0.1, 10.1)
    ax.set_ylim(-0.1, 7.2)
    ax.axis("off")
    fig.tight_layout()
    fig.savefig(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
