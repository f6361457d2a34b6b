"""meshpde: Laplacian and bi-Laplacian PDEs solved directly on triangle meshes.

Plain data in and out, as in libigl: ``V`` is an (n, 3) float64 array of vertex
positions and ``F`` an (m, 3) integer array of zero-based triangle corners; float32,
int64 and Fortran-ordered arrays are converted. Results are numpy arrays, operators
``scipy.sparse.csr_matrix``. Units are the mesh's own (millimetres for vessels).

Conventions (docs/mathematics.md):

- ``stiffness(V, F)`` is K, symmetric positive semi-definite with K 1 = 0: the
  *opposite* sign of libigl's ``cotmatrix`` (``K == -igl.cotmatrix(V, F)``).
- ``mass(V, F)`` is the lumped mass M, M_ii = one third of the area around vertex i.
- The bi-Laplacian is K M^-1 K.

Errors: ``meshpde.InputError`` (a ``ValueError``) for unusable input, naming the
argument, file, line or element; ``IndexError`` for an index out of range;
``meshpde.SolverError`` (a ``RuntimeError``) when a solve cannot proceed. Long calls
release the GIL; ``heat`` and ``wave`` stop on Ctrl-C with ``KeyboardInterrupt``.

``meshpde.batch`` (imported on its own: ``import meshpde.batch``) runs one of these
over many mesh files on a Dask cluster (docs/batch.md).
"""

from __future__ import annotations

from . import _meshpde
from ._meshpde import (  # noqa: F401  (re-exported)
    CorrectionResult,
    DragSession,
    Error,
    GlobalBilaplacianSolver,
    HapticSession,
    InputError,
    PdeSession,
    SolverError,
    check_units,
    curvature,
    generate,
    geodesic_ball,
    info,
    intrinsic_delaunay,
    mass,
    read_mesh,
    render,
    ring_ball,
    hausdorff_distance,
    self_intersections,
    stiffness,
    vertex_normals,
    wave_energy,
    write_mesh,
)

from .interop import from_vtk, to_vtk  # noqa: F401,E402

__version__ = _meshpde.__version__
has_medical = _meshpde.has_medical
if has_medical:
    from ._meshpde import read_volume  # noqa: F401

__all__ = [
    "CorrectionResult", "CorrectionSession", "DragSession", "Error", "GlobalBilaplacianSolver", "HapticSession",
    "InputError", "PdeSession", "SolverError", "check_units", "correct", "curvature", "fair", "from_vtk", "generate",
    "geodesic_ball", "heat", "info", "interpolate", "intrinsic_delaunay", "mass", "read_mesh", "read_volume",
    "hausdorff_distance", "render", "ring_ball", "self_intersections", "stiffness", "to_vtk", "vertex_normals", "wave", "wave_energy",
    "write_mesh",
]


def heat(V, F, *, sources=None, flux=None, dt=1e-3, steps=100, diffusivity=1.0, initial=None, local=False,
         laplacian="auto", callback=None):
    """Heat diffusion u_t = k lap(u) by backward Euler, as ``meshpde heat``.

    sources: {vertex: value} (or (vertex, value) pairs) held every step.
    flux: {vertex: rate}, a point load in value x area per second.
    dt (s), steps, diffusivity k (length^2/s); initial: (n,) start values (default 0).
    local: solve on a self-adjusting active domain instead of the whole mesh.
    laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes),
    "cotan" or "intrinsic", as ``--laplacian``.
    callback(step, u, u_t): called after each step (step = 1..steps).

    Returns a namespace with ``values`` (n,), ``velocity`` (n,), ``cg_iterations``
    and ``max_free_vertices``.
    """
    return _meshpde._heat(V, F, sources, flux, dt, steps, diffusivity, initial, local, laplacian, callback)


def wave(V, F, *, sources=None, flux=None, impulses=None, dt=1e-3, steps=100, speed=1.0, damping=0.0, initial=None,
         initial_velocity=None, local=False, laplacian="auto", callback=None):
    """Wave propagation u_tt + b u_t = c^2 lap(u), as ``meshpde wave``.

    impulses: {vertex: velocity} added to the initial velocity; speed c (length/s),
    damping b (1/s); other arguments as in :func:`heat`. Backward Euler loses a
    factor 1 / (1 + w^2 dt^2) of a mode's energy per step (keep w dt small).
    Returns the same namespace as :func:`heat`.
    """
    return _meshpde._wave(V, F, sources, flux, impulses, dt, steps, speed, damping, initial, initial_velocity, local,
                          laplacian, callback)


def fair(V, F, fixed, *, order=2, regularize=False, dt=1.0, steps=15, damping=0.0, solver="auto",
         laplacian="auto"):
    """Fairing: the free vertices solve the membrane (order 1) or thin-plate (order 2)
    equation with ``fixed`` held, as ``meshpde fair``.

    fixed: vertex indices, or selection specs as ``--fixed`` takes them ("boundary",
    "rings:V:K", "radius:V:R", "halfspace:NX,NY,NZ:D", "all", ...).
    regularize: seed 000's area-weighted membrane flow (``steps`` steps of ``dt``).
    solver: "auto" (default: with order 2, the multigrid on meshes of 50,000 free
    vertices or more without angles under 20 degrees, kept where it converges; else
    "direct"), "direct" (sparse Cholesky), "global" (multigrid-CG, order 2) or
    "iterative".
    laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes),
    "cotan" or "intrinsic"; ``regularize`` always uses area-weighted cotangent operators.

    Returns a namespace with ``V`` (n, 3), triangle quality ``before`` and ``after``
    (dicts), ``cg_iterations``, ``worst_residual``, ``solver`` (the one that ran: "direct",
    "global" or "iterative"), ``laplacian`` (the operators used) and ``laplacian_reason``.
    """
    return _meshpde._fair(V, F, fixed, order, regularize, dt, steps, damping, solver, laplacian)


def interpolate(V, F, vertices, values, *, kind=None, method="componentwise", g1=0.0, g2=1.0, solver="auto",
                laplacian="auto"):
    """Scattered-data interpolation (g1 K + g2 K D K) u = 0 with u given at ``vertices``.

    values: (k,) for scalars, (k, 3) for displacements or tangent vectors.
    kind: "scalar", "displacement" or "tangent" (default: scalar for 1-D values,
    displacement for (k, 3)). method (tangent only): "componentwise" or "connection".
    g2 > 0 reproduces linear fields exactly; g1 alone gives spikes.
    laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes; tangent
    fields always use the cotangent operators of the input triangles), "cotan" or "intrinsic".
    solver: "auto" (default: with g2 > 0, the multigrid on meshes of 50,000 free
    vertices or more without angles under 20 degrees, kept where it converges; else
    "direct"), "direct", "global" (multigrid-CG; g2 > 0) or "iterative" (Jacobi-CG).
    Returns (n,) or (n, 3).
    """
    if kind is None:
        import numpy as np
        kind = "scalar" if np.ndim(values) == 1 else "displacement"
    return _meshpde._interpolate(V, F, vertices, values, kind, method, g1, g2, solver, laplacian)


def _correction_options(radius, rings, method, g1, g2, laplacian, stiffness, dynamic, steps, mass, elasticity,
                        viscosity, allow_intersections, max_substeps, image, space, image_weight, image_sigma,
                        search_radius, cube, passes, solver, units, boundary="clamp"):
    return dict(units=units, radius=radius, rings=rings, method=method, boundary=boundary, g1=g1, g2=g2,
                laplacian=laplacian,
                stiffness=stiffness, dynamic=dynamic, steps=steps, mass=mass, elasticity=elasticity, viscosity=viscosity,
                allow_intersections=allow_intersections, max_substeps=max_substeps, image=image, space=space,
                image_weight=image_weight, image_sigma=image_sigma, search_radius=search_radius, cube=cube,
                passes=passes, solver=solver)


_CORRECT_DOC = """
    vertices: handle vertex indices; moves: one per handle, (dx, dy, dz) in mm
    or "normal:D" (D mm along the outward normal, outward even on inward-oriented meshes).
    units: "mm" (default), "cm" or "m", the unit of V's coordinates; every length given
    here is in mm whatever it is, and V and displacement come back in V's unit (a
    UserWarning names a mesh whose size is unlike a vessel's in that unit).
    radius: region of influence, edge-path distance from a handle (mm), or
    rings: the region in rings of neighbours (the thesis's level of influence).
    method: "fem" (bi-Laplacian, ours) or "springs" (the thesis's mass-spring baseline).
    boundary: how a fem region given by radius ends: "clamp" (default: held at the
    radius) or "fade" (an elastic foundation from 0.6 radius, free to twice the radius:
    results on two resolutions of a surface agree about three times better).
    g1, g2: membrane and plate stiffness (default 0, 1).
    laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes),
    "cotan" or "intrinsic".
    stiffness: (n,) per-vertex tissue stiffness multiplier (> 0), default 1.
    dynamic, steps, mass, elasticity, viscosity: settle like tissue (thesis defaults
    0.1, 0.9, 0.6) instead of the static solve; each of the three is a number in [0, 1]
    or an (n,) array of them, one per vertex (elasticity then weighs the static solve
    too, relative to its largest value).
    allow_intersections: do not split or limit a correction that would make the
    surface intersect itself (default False); max_substeps: how far it is split.
    image: a volume path (.mha .nii .nii.gz .nrrd), or a (values[i, j, k], affine)
    pair with the voxel-to-LPS-mm affine of :func:`read_volume`: pull the wall onto
    its edges. space: "lps" or "ras", the frame of V. image_weight (30),
    image_sigma (1 mm), search_radius (3 mm), cube (0: off), passes (4).
    solver: "auto" (default: for a static, unguided fem region of 50,000 free vertices
    or more without angles under 20 degrees, the multigrid, kept where it converges;
    else "direct"), "direct", "global" (multigrid-CG, for very large regions) or
    "iterative" (Jacobi-CG); the last two for the static fem correction without image.
    The result's ``solver`` says which one ran.

    Returns a :class:`CorrectionResult`: V, displacement, region and the report fields
    of ``meshpde correct --json`` under the same names (``to_dict()`` gives them all).
"""


def correct(V, F, vertices, moves, *, radius=0.0, rings=0, method="fem", g1=0.0, g2=1.0, laplacian="auto",
            stiffness=None, dynamic=False, steps=50, mass=0.1, elasticity=0.9, viscosity=0.6,
            allow_intersections=False, max_substeps=8, image=None, space="lps", image_weight=30.0, image_sigma=1.0,
            search_radius=3.0, cube=0, passes=4, solver="auto", units="mm", boundary="clamp"):
    return _meshpde._correct(V, F, vertices, moves, _correction_options(
        radius, rings, method, g1, g2, laplacian, stiffness, dynamic, steps, mass, elasticity, viscosity,
        allow_intersections, max_substeps, image, space, image_weight, image_sigma, search_radius, cube, passes,
        solver, units, boundary))


correct.__doc__ = "Vessel-wall correction (seed 001), as ``meshpde correct``; the input is not modified.\n" + _CORRECT_DOC


class CorrectionSession(_meshpde._CorrectionSession):
    """Corrections applied on top of each other to one mesh, with undo and redo.

    ``V`` is the current positions, ``original`` the first ones.
    """

    def apply(self, vertices, moves, *, radius=0.0, rings=0, method="fem", g1=0.0, g2=1.0, laplacian="auto",
              stiffness=None, dynamic=False, steps=50, mass=0.1, elasticity=0.9, viscosity=0.6,
              allow_intersections=False, max_substeps=8, image=None, space="lps", image_weight=30.0,
              image_sigma=1.0, search_radius=3.0, cube=0, passes=4, solver="auto", units="mm", boundary="clamp"):
        return self._apply(vertices, moves, _correction_options(
            radius, rings, method, g1, g2, laplacian, stiffness, dynamic, steps, mass, elasticity, viscosity,
            allow_intersections, max_substeps, image, space, image_weight, image_sigma, search_radius, cube, passes,
            solver, units, boundary))

    apply.__doc__ = "Applies a correction to the current positions; clears the redo history.\n" + _CORRECT_DOC
