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

Errors: every one a ``meshpde.Error``. ``meshpde.InputError`` (also a ``ValueError``)
for unusable input, naming the argument, file, line or element;
``meshpde.OutOfRangeError`` (an ``InputError`` and an ``IndexError``) for an index out
of range; ``meshpde.SolverError`` (a ``RuntimeError``) when a solve cannot proceed. Long calls
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
    OutOfRangeError,
    GlobalBilaplacianSolver,
    HapticSession,
    InputError,
    InterpolationSolver,
    PdeSession,
    SolverError,
    check_units,
    closest_surface_points,
    quadratic_reading,
    curvature,
    generate,
    geodesic_ball,
    geodesic_distance,
    info,
    intrinsic_delaunay,
    mass,
    render,
    ring_ball,
    hausdorff_distance,
    self_intersections,
    stiffness,
    vertex_normals,
    wave_energy,
)



class MeshFields(dict):
    """The vertex fields of a mesh file by name (this is a dict), and what else the file
    carried, which :func:`write_mesh` writes back:

    - ``cells``: cell data by name (SimVascular's ``ModelFaceID``, VMTK's
      ``CellEntityIds``), an (m,) or (m, k) array a row per triangle (a polygon's row
      repeated for each of its triangles), in the file's type (Int32 as int32);
    - ``space``: the frame the file names ("LPS" or "RAS", 3D Slicer's tag), or None;
    - ``field_data``: data about the whole mesh (.vtp), strings and small arrays.

    Vertex fields keep their file's type too (an Int32 array comes as int32 and is
    written as Int32).
    """

    def __init__(self, fields=(), cells=None, space=None, field_data=None):
        super().__init__(fields)
        self.cells = dict(cells or {})
        self.space = space
        self.field_data = dict(field_data or {})

    def copy(self):
        return MeshFields(self, self.cells, self.space, self.field_data)


def read_mesh(path):
    """(V, F, fields) of a mesh file: V (n, 3) float64, F (m, 3) int32, and a
    :class:`MeshFields`: the vertex fields by name ((n,) or (n, k) arrays in the file's
    types; NAME_x/_y/_z joined into (n, 3)), with the file's cell arrays in
    ``fields.cells``, its frame in ``fields.space`` and its field data in
    ``fields.field_data``. OBJ, OFF, PLY, STL and, with the medical component, .vtp and
    .vtk. Raises FileNotFoundError, or InputError naming the file and line or element.
    """
    V, F, fields, cells, space, field_data = _meshpde._read_mesh(path)
    return V, F, MeshFields(fields, cells, space, field_data)


def write_mesh(path, V, F, fields=None, binary=True, *, cells=None, space=None, field_data=None):
    """Writes a mesh by extension, atomically (a temporary file renamed over the target).

    fields: vertex fields by name, (n,) or (n, k) arrays, written in their dtype (int32
    as Int32, float32 as Float32; others as Float64). cells: cell data by name, a row
    per triangle; space: "LPS" or "RAS" (3D Slicer's frame tag); field_data: strings and
    small arrays about the whole mesh. When ``fields`` is the :class:`MeshFields` that
    :func:`read_mesh` gave, its cells, space and field data are written unless given
    here. What a format cannot hold (cell data outside .vtp and .vtk, vertex fields in
    OBJ, OFF and STL) is dropped with a UserWarning; the warnings are returned too.
    """
    if isinstance(fields, MeshFields):
        cells = fields.cells if cells is None else cells
        space = fields.space if space is None else space
        field_data = fields.field_data if field_data is None else field_data
    return _meshpde._write_mesh(path, V, F, None if fields is None else dict(fields), binary, cells, space,
                                field_data)


from .interop import from_vtk, to_vtk  # noqa: F401,E402

__version__ = _meshpde.__version__
has_medical = _meshpde.has_medical
if has_medical:
    from ._meshpde import read_volume  # noqa: F401

__all__ = [
    "CorrectionResult", "CorrectionSession", "DragSession", "Error", "GlobalBilaplacianSolver", "HapticSession",
    "InputError", "InterpolationSolver", "MeshFields", "OutOfRangeError", "PdeSession", "SolverError", "check_units", "closest_surface_points", "correct", "curvature", "extract_surface", "fair",
    "from_vtk", "generate", "geodesic_ball", "geodesic_distance", "heat", "info", "interpolate", "intrinsic_delaunay", "mass", "quadratic_reading", "read_mesh",
    "read_segmentation", "read_volume", "voxelize", "write_segmentation",
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
         laplacian="auto", tolerance=1e-10):
    """Fairing: the free vertices solve the membrane (order 1) or thin-plate (order 2)
    equation with ``fixed`` held, as ``meshpde fair``.

    fixed: vertex indices, or selection specs as ``--fixed`` takes them ("boundary",
    "rings:V:K", "radius:V:R", "halfspace:NX,NY,NZ:D", "all", ...).
    regularize: Kim and Rossignac's area-weighted membrane flow (``steps`` steps of ``dt``).
    solver: "auto" (default: with order 2, the multigrid on meshes of 50,000 free
    vertices or more without angles under 20 degrees, kept where it converges; else
    "direct"), "direct" (sparse Cholesky), "global" (multigrid-CG, order 2) or
    "iterative".
    laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes),
    "cotan" or "intrinsic"; ``regularize`` always uses area-weighted cotangent operators.
    tolerance: CG's relative residual for solver="iterative" and the regularization's
    steps (between 0 and 1; default 1e-10).

    Returns a namespace with ``V`` (n, 3), triangle quality ``before`` and ``after``
    (dicts), ``cg_iterations``, ``worst_residual``, ``solver`` (the one that ran: "direct",
    "global" or "iterative"), ``laplacian`` (the operators used) and ``laplacian_reason``.
    """
    return _meshpde._fair(V, F, fixed, order, regularize, dt, steps, damping, solver, laplacian, tolerance)


def interpolate(V, F, vertices, values, *, kind=None, method="componentwise", g1=0.0, g2=1.0, solver="auto",
                laplacian="auto", tolerance=1e-11):
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
    tolerance: CG's relative residual for solver="iterative" (between 0 and 1; default 1e-11).
    Returns (n,) or (n, 3).
    """
    if kind is None:
        import numpy as np
        kind = "scalar" if np.ndim(values) == 1 else "displacement"
    return _meshpde._interpolate(V, F, vertices, values, kind, method, g1, g2, solver, laplacian, tolerance)


def _correction_options(*, radius, rings, method, g1, g2, laplacian, stiffness, dynamic, steps, mass, elasticity,
                        viscosity, brushes, allow_intersections, max_substeps, image, space, image_weight, image_sigma,
                        search_radius, cube, passes, solver, tolerance, units, boundary, caps, face_labels, points,
                        handle_radius):
    """The options of ``correct`` and ``CorrectionSession.apply`` as the extension takes them (by name only)."""
    return dict(units=units, radius=radius, rings=rings, method=method, boundary=boundary, g1=g1, g2=g2,
                points=points, handle_radius=handle_radius,
                laplacian=laplacian,
                stiffness=stiffness, dynamic=dynamic, steps=steps, mass=mass, elasticity=elasticity, viscosity=viscosity,
                brushes=brushes, allow_intersections=allow_intersections, max_substeps=max_substeps, image=image, space=space,
                image_weight=image_weight, image_sigma=image_sigma, search_radius=search_radius, cube=cube,
                passes=passes, solver=solver, tolerance=tolerance, caps=caps, face_labels=face_labels)


_CORRECT_DOC = """
    vertices: handle vertex indices (or "@X,Y,Z", the vertex nearest to that point);
    points: (k, 3) handle points in V's coordinates, each the surface point nearest to
    it, which moves (not a vertex); moves: one per handle, the vertices' first, then the
    points', (dx, dy, dz) in mm or "normal:D" (D mm along the outward normal, outward
    even on inward-oriented meshes; at a point, the corners' normals interpolated).
    handle_radius: the handles' size in mm: the surface within it carries the force that
    moves the handle, a smooth bump instead of a cusp; 0 is a single point. Default
    (negative): a quarter of radius with the smooth boundary, 0 with clamp and fade.
    units: "mm" (default), "cm" or "m", the unit of V's coordinates; every length given
    here is in mm whatever it is, and V and displacement come back in V's unit (a
    UserWarning names a mesh whose size is unlike a vessel's in that unit).
    radius: region of influence, distance from a handle (mm) on the surface (smooth
    boundary) or along edges (clamp, fade), or
    rings: the region in rings of neighbours (the thesis's level of influence).
    method: "fem" (bi-Laplacian, ours) or "springs" (the thesis's mass-spring baseline).
    boundary: how a fem region given by radius ends: "smooth" (default: the displacement
    and its slope fall to zero at radius on the surface, the same on any triangulation
    of it), "clamp" (held beyond radius - h by edge paths: the rule before smooth) or
    "fade" (an elastic foundation from 0.6 radius, free to twice the radius).
    g1, g2: membrane and plate stiffness (default 0, 1).
    laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes),
    "cotan" or "intrinsic".
    stiffness: (n,) per-vertex tissue stiffness multiplier (> 0), default 1.
    dynamic, steps, mass, elasticity, viscosity: settle like tissue (thesis defaults
    0.1, 0.9, 0.6) instead of the static solve; each of the three is a number in [0, 1]
    or an (n,) array of them, one per vertex (elasticity then weighs the static solve
    too, relative to its largest value).
    brushes: tissue brushes painted in order over those, each "[PROPERTY:]V:RADIUS:VALUE"
    as ``meshpde correct --brush`` takes it (PROPERTY stiffness, the default, mass,
    elasticity or viscosity; V a vertex index or "@X,Y,Z"; RADIUS in mm).
    allow_intersections: do not split or limit a correction that would make the
    surface intersect itself (default False); max_substeps: the guard's smallest step
    is 1 / max_substeps of the displacement (default 8; 1 only limits the one-shot field). A
    correction that is limited says so with a UserWarning.
    face_labels: (m,) a label per triangle (``fields.cells["ModelFaceID"]`` or
    ``["CellEntityIds"]`` of :func:`read_mesh`); caps: "labels" (default: the flat
    labelled patches, other than the wall, are caps), "auto" (labels, else flat patches
    with a sharp rim found by shape) or "off". A cap's vertices, its rim included, never
    move; the report's ``caps`` says how many were held.
    image: a volume path (.mha .nii .nii.gz .nrrd), or a (values[i, j, k], affine)
    pair with the voxel-to-LPS-mm affine of :func:`read_volume`: pull the wall onto
    its edges. space: "lps" or "ras", the frame of V. image_weight (30),
    image_sigma (1 mm), search_radius (3 mm), cube (0: off), passes (4).
    solver: "auto" (default: for a static, unguided fem region of 50,000 free vertices
    or more without angles under 20 degrees, the multigrid, kept where it converges;
    else "direct"), "direct", "global" (multigrid-CG, for very large regions) or
    "iterative" (Jacobi-CG); the last two for the static fem correction without image,
    with boundary="clamp" and vertex handles of size 0. tolerance: CG's relative
    residual for solver="iterative" (between 0 and 1; default 1e-10).
    The result's ``solver`` says which one ran.

    Returns a :class:`CorrectionResult`: V, displacement, region and the report fields
    of ``meshpde correct --json`` under the same names (``to_dict()`` gives them all).
"""


def correct(V, F, vertices=None, moves=None, *, points=None, handle_radius=-1.0, radius=0.0, rings=0, method="fem", g1=0.0, g2=1.0, laplacian="auto",
            stiffness=None, dynamic=False, steps=50, mass=0.1, elasticity=0.9, viscosity=0.6, brushes=None,
            allow_intersections=False, max_substeps=8, image=None, space="lps", image_weight=30.0, image_sigma=1.0,
            search_radius=3.0, cube=0, passes=4, solver="auto", tolerance=1e-10, units="mm", boundary="smooth",
            caps="labels", face_labels=None):
    return _meshpde._correct(V, F, vertices, moves, _correction_options(
        radius=radius, rings=rings, method=method, g1=g1, g2=g2, laplacian=laplacian, stiffness=stiffness,
        dynamic=dynamic, steps=steps, mass=mass, elasticity=elasticity, viscosity=viscosity, brushes=brushes,
        allow_intersections=allow_intersections, max_substeps=max_substeps, image=image, space=space,
        image_weight=image_weight, image_sigma=image_sigma, search_radius=search_radius, cube=cube, passes=passes,
        solver=solver, tolerance=tolerance, units=units, boundary=boundary, caps=caps, face_labels=face_labels,
        points=points, handle_radius=handle_radius))


correct.__doc__ = "Vessel-wall correction (Schoenmaker's thesis), as ``meshpde correct``; the input is not modified.\n" + _CORRECT_DOC


class CorrectionSession(_meshpde._CorrectionSession):
    """Corrections applied on top of each other to one mesh, with undo and redo.

    ``V`` is the current positions, ``original`` the first ones.
    """

    def apply(self, vertices=None, moves=None, *, points=None, handle_radius=-1.0, radius=0.0, rings=0, method="fem", g1=0.0, g2=1.0, laplacian="auto",
              stiffness=None, dynamic=False, steps=50, mass=0.1, elasticity=0.9, viscosity=0.6, brushes=None,
              allow_intersections=False, max_substeps=8, image=None, space="lps", image_weight=30.0,
              image_sigma=1.0, search_radius=3.0, cube=0, passes=4, solver="auto", tolerance=1e-10, units="mm",
              boundary="smooth", caps="labels", face_labels=None):
        return self._apply(vertices, moves, _correction_options(
            radius=radius, rings=rings, method=method, g1=g1, g2=g2, laplacian=laplacian, stiffness=stiffness,
            dynamic=dynamic, steps=steps, mass=mass, elasticity=elasticity, viscosity=viscosity, brushes=brushes,
            allow_intersections=allow_intersections, max_substeps=max_substeps, image=image, space=space,
            image_weight=image_weight, image_sigma=image_sigma, search_radius=search_radius, cube=cube,
            passes=passes, solver=solver, tolerance=tolerance, units=units, boundary=boundary, caps=caps,
            face_labels=face_labels, points=points, handle_radius=handle_radius))

    apply.__doc__ = "Applies a correction to the current positions; clears the redo history.\n" + _CORRECT_DOC


def _labels_array(d):
    """(labels, affine, segments) of the extension's segmentation dict."""
    import numpy as np
    ni, nj, nk = d["dims"]
    layers = d["layers"]
    labels = np.asarray(d["labels"]).reshape((layers, ni, nj, nk), order="F")
    labels = np.moveaxis(labels, 0, -1)
    if layers == 1:
        labels = labels[..., 0]
    return labels, np.asarray(d["affine"]), list(d["segments"])


def _flat_labels(labels):
    """The extension's flat labels (layer fastest, then i, j, k), dims and layers."""
    import numpy as np
    a = np.asarray(labels)
    if a.ndim not in (3, 4):
        raise InputError(f"labels: expected an array [i, j, k] or [i, j, k, layer], got {a.ndim} dimensions")
    if not np.issubdtype(a.dtype, np.integer):
        if not np.all(np.isfinite(a)) or not np.all(a == np.round(a)):
            raise InputError("labels: a label map holds whole numbers")
    if a.size and (a.min() < np.iinfo(np.int32).min or a.max() > np.iinfo(np.int32).max):
        raise InputError("labels: values beyond int32")
    if a.ndim == 3:
        a = a[..., None]
    flat = np.moveaxis(a.astype(np.int32), -1, 0).ravel(order="F")
    return np.ascontiguousarray(flat), tuple(int(n) for n in a.shape[:3]), int(a.shape[3])


def read_segmentation(path):
    """A segmentation file: 3D Slicer's .seg.nrrd, or a label map (.nii, .nii.gz, .nrrd,
    .nhdr, .mha, .mhd).

    Returns ``(labels, affine, segments)``: ``labels[i, j, k]`` int32 (``[i, j, k,
    layer]`` for a .seg.nrrd of several layers), the 4 x 4 affine from voxel indices to
    LPS millimetres (as :func:`read_volume`), and the segment table: a list of dicts
    with ``name``, ``id``, ``label`` (its voxel value), ``layer``, ``color`` (RGB in
    [0, 1]) and ``index`` (the N of the file's SegmentN_ fields). A plain label map has a
    segment for each non-zero label, named "label N".
    """
    return _labels_array(_meshpde._read_segmentation(path))


def write_segmentation(path, labels, affine, segments=None, *, like=None):
    """Writes a segmentation (by extension: .seg.nrrd, .nrrd, .nii, .nii.gz, .mha),
    atomically.

    like: a segmentation file on the same grid whose header is kept (every field, key,
    comment and segment, the voxel type and compression; a .seg.nrrd segment's Extent is
    widened to its voxels): the way to write back a segmentation read with
    :func:`read_segmentation` so that 3D Slicer reopens it as it was but for the voxels.
    Without it the header is made from the affine, and ``segments`` (dicts as
    :func:`read_segmentation` returns; default: one a label) become a .seg.nrrd's table.
    """
    flat, dims, layers = _flat_labels(labels)
    _meshpde._write_segmentation(path, flat, dims, layers, affine, segments, like)


def extract_surface(segmentation, segment=None, *, smoothing=0.15, affine=None):
    """The closed surface of one segment, as 3D Slicer's closed-surface conversion makes
    it (flying edges, then windowed-sinc smoothing), in LPS millimetres.

    segmentation: a file (as :func:`read_segmentation` reads), or a labels array with
    ``affine``. segment: its name, ID or label value (default: the only segment).
    smoothing: 3D Slicer's factor, 0 (none) to 1 (strong); default 0.15.
    Returns ``(V, F, info)``: info holds the segment (name, id, label, layer, color),
    its voxel count, the smoothing and the frame ("LPS").
    """
    if isinstance(segmentation, (str, bytes)) or hasattr(segmentation, "__fspath__"):
        return _meshpde._extract_surface(segmentation, None, (0, 0, 0), 1, None, "" if segment is None else str(segment),
                                         smoothing)
    if affine is None:
        raise InputError("extract_surface: a labels array needs its affine")
    flat, dims, layers = _flat_labels(segmentation)
    return _meshpde._extract_surface(None, flat, dims, layers, affine, "" if segment is None else str(segment),
                                     smoothing)


def voxelize(V, F, reference, segment=None, *, displacement=None, oversampling=1, full=False, output=None,
             space="lps", units="mm", series=None):
    """A closed surface back into a label map on the grid of ``reference``.

    reference: a segmentation (.seg.nrrd, or a label map: whole non-negative values, at
    most 1,000 labels), whose ``segment`` (name, ID or label value; default the only one)
    is replaced and every other segment kept; or an image (any volume, DICOM too; its
    ``series``), whose grid gets a new label map.
    displacement: (n, 3), how far each vertex moved (the ``displacement`` field that
    :func:`correct` and ``meshpde correct`` give): only the voxels between the surface
    before and after the move are decided again, every other voxel keeps its label.
    Without it, or with full=True, every voxel of the segment is decided again.
    oversampling: K sub-samples along each axis of a voxel (inside when more than half
    are). space, units: the frame ("lps" or "ras") and unit ("mm", "cm" or "m") of V.
    output: a file to write (as :func:`write_segmentation` with ``like=reference``).
    Returns ``(labels, affine, segments, report)``; the report counts the voxels
    ``added``, ``removed`` and left to other segments (``conflicts``), and says whether
    the update was ``partial``.
    """
    d, report = _meshpde._voxelize(V, F, displacement, reference, "" if segment is None else str(segment),
                                   oversampling, full, space, units, series, output)
    return (*_labels_array(d), report)
