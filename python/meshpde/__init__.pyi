# Type stubs of the meshpde package (the compiled _meshpde plus the Python layer).
# Shapes: n vertices, m triangles, k handles/constraints. Units: the mesh's own.
from os import PathLike
from types import SimpleNamespace
from typing import Any, Callable, Mapping, Sequence, Union

import numpy as np
import numpy.typing as npt
import scipy.sparse

ArrayLike = npt.ArrayLike
Path = Union[str, PathLike]
Move = Union[str, Sequence[float]]  # (dx, dy, dz) or "normal:D"

__version__: str
has_medical: bool

class Error(RuntimeError): ...
class InputError(Error, ValueError): ...
class OutOfRangeError(InputError, IndexError): ...
class SolverError(Error): ...

# --- mesh: files, diagnostics, generators ----------------------------------------
class MeshFields(dict[str, np.ndarray]):
    """Vertex fields by name (in their file's types), and the file's cell arrays, frame and field data."""
    cells: dict[str, np.ndarray]  # a row per triangle: ModelFaceID, CellEntityIds, ...
    space: str | None  # "LPS", "RAS" or None
    field_data: dict[str, Any]  # strings and small arrays about the whole mesh
    def __init__(self, fields: Mapping[str, np.ndarray] = ..., cells: Mapping[str, np.ndarray] | None = None,
                 space: str | None = None, field_data: Mapping[str, Any] | None = None) -> None: ...
    def copy(self) -> MeshFields: ...
def read_mesh(path: Path) -> tuple[np.ndarray, np.ndarray, MeshFields]:
    """(V (n, 3) float64, F (m, 3) int32, MeshFields: vertex fields, .cells, .space, .field_data)."""
def write_mesh(path: Path, V: ArrayLike, F: ArrayLike, fields: Mapping[str, ArrayLike] | None = None,
               binary: bool = True, *, cells: Mapping[str, ArrayLike] | None = None, space: str | None = None,
               field_data: Mapping[str, Any] | None = None) -> list[str]:
    """Writes atomically by extension, arrays in their dtypes; a MeshFields brings its cells, space and field data."""
def read_volume(path: Path, series: str | int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(values[i, j, k] float32, 4x4 voxel-to-LPS-mm affine); .mha .mhd .nii .nii.gz .nrrd .nhdr, DICOM."""
def read_segmentation(path: Path) -> tuple[np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """(labels[i, j, k] (or [i, j, k, layer]) int32, 4x4 affine to LPS mm, segments); .seg.nrrd and label maps."""
def write_segmentation(path: Path, labels: ArrayLike, affine: ArrayLike,
                       segments: Sequence[Mapping[str, Any]] | None = None, *, like: Path | None = None) -> None:
    """Writes a segmentation atomically; `like`: a file on the same grid whose header is kept."""
def extract_surface(segmentation: Union[Path, ArrayLike], segment: str | int | None = None, *,
                    smoothing: float = 0.15, affine: ArrayLike | None = None
                    ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """(V in LPS mm, F, info) of one segment's closed surface (flying edges, windowed-sinc smoothing)."""
def voxelize(V: ArrayLike, F: ArrayLike, reference: Path, segment: str | int | None = None, *,
             displacement: ArrayLike | None = None, oversampling: int = 1, full: bool = False,
             output: Path | None = None, space: str = "lps", units: str = "mm", series: str | int | None = None
             ) -> tuple[np.ndarray, np.ndarray, list[dict[str, Any]], dict[str, Any]]:
    """(labels, affine, segments, report): a closed surface back into a segment on the reference's grid."""
def info(V: Union[ArrayLike, Path], F: ArrayLike | None = None) -> dict[str, Any]:
    """`meshpde info --json` of (V, F), or of a mesh or volume file."""
def vertex_normals(V: ArrayLike, F: ArrayLike, outward: bool = True) -> np.ndarray:
    """(n, 3) unit normals; outward: away from the enclosed volume of a closed mesh."""
def geodesic_ball(V: ArrayLike, F: ArrayLike, vertex: int, radius: float) -> np.ndarray:
    """Vertices within edge-path distance `radius` of `vertex`, nearest first."""
def closest_surface_points(V: ArrayLike, F: ArrayLike, points: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(faces (k,), barycentric (k, 3)) of the surface point nearest to each point."""
def quadratic_reading(V: ArrayLike, F: ArrayLike, points: ArrayLike) -> scipy.sparse.csr_matrix:
    """scipy.sparse.csr_matrix (k, n): W @ field reads a vertex field at the nearest surface points to second order."""
def geodesic_distance(V: ArrayLike, F: ArrayLike, sources: ArrayLike, radius: float = ...) -> np.ndarray:
    """(n,) distance along the surface from the nearest source (vertex indices or (k, 3) points); inf beyond radius."""
def ring_ball(V: ArrayLike, F: ArrayLike, vertex: int, rings: int) -> np.ndarray:
    """Vertices within `rings` edges of `vertex`."""
def hausdorff_distance(VA: ArrayLike, FA: ArrayLike, VB: ArrayLike, FB: ArrayLike, directed: bool = False) -> float:
    """Symmetric (or, directed=True, A to B) Hausdorff distance between two triangle surfaces."""
def self_intersections(V: ArrayLike, F: ArrayLike) -> np.ndarray:
    """(p, 2) pairs of intersecting triangles."""
def render(V: ArrayLike, F: ArrayLike, field: ArrayLike | None = None, vectors: ArrayLike | None = None,
           path: Path | None = None, width: int = 960, height: int = 720, azimuth: float = 30.0,
           elevation: float = 20.0, up: str = "y", zoom: float = 1.0, center: ArrayLike | None = None,
           wireframe: bool = False, colormap: str = "viridis", range: ArrayLike | None = None, title: str = "",
           field_name: str = "") -> np.ndarray | None:
    """An (height, width, 3) uint8 picture, or None after writing a PNG to `path`."""

class generate:
    """The generator table of `meshpde generate`; each returns (V, F)."""
    @staticmethod
    def names() -> list[str]: ...
    @staticmethod
    def latlong(n: int = 15, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]: ...
    @staticmethod
    def icosphere(level: int = 3, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]: ...
    @staticmethod
    def geodesic(base: str = "icosahedron", frequency: int = 4, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]: ...
    @staticmethod
    def tube(radius: float = 1.0, length: float = 10.0, rings: int = 20, segments: int = 24) -> tuple[np.ndarray, np.ndarray]: ...
    @staticmethod
    def plane(nx: int = 20, ny: int = 20, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]: ...
    @staticmethod
    def fins(k: int = 3, n: int = 15) -> tuple[np.ndarray, np.ndarray]: ...
    @staticmethod
    def bifurcation(cell: float = 0.6, dent: bool = False, trunk_radius: float = 4.0, branch_radius: float = 3.0,
                    trunk_length: float = 20.0, branch_length: float = 18.0, angle_deg: float = 60.0,
                    dent_depth: float = 1.5, dent_radius: float = 3.0) -> tuple[np.ndarray, np.ndarray]: ...
    @staticmethod
    def subdivide(V: ArrayLike, F: ArrayLike) -> tuple[np.ndarray, np.ndarray]: ...

# --- operators ----------------------------------------------------------------------
def stiffness(V: ArrayLike, F: ArrayLike, laplacian: str = "cotan") -> scipy.sparse.csr_matrix:
    """K (n x n), symmetric positive semi-definite, K 1 = 0: minus libigl's cotmatrix."""
def mass(V: ArrayLike, F: ArrayLike, laplacian: str = "cotan") -> scipy.sparse.csr_matrix:
    """Lumped mass M (n x n diagonal, length^2)."""
def intrinsic_delaunay(V: ArrayLike, F: ArrayLike, mollify_epsilon: float = 1e-2
                       ) -> tuple[scipy.sparse.csr_matrix, scipy.sparse.csr_matrix, dict[str, Any]]:
    """(K, M, stats) on the intrinsic Delaunay triangulation: an M-matrix on any mesh."""
def check_units(V: ArrayLike, F: ArrayLike, units: str = "mm") -> dict[str, Any]:
    """Sizes in mm when V is read in `units`; `implausible` for a vessel, and the unit `suggested`."""
def curvature(V: ArrayLike, F: ArrayLike, scale: str = "area", laplacian: str = "auto") -> np.ndarray:
    """Mean curvature per vertex (1 / length); scale "area" or "valence"; laplacian "auto", "cotan", "intrinsic"."""

# --- applications ---------------------------------------------------------------------
def heat(V: ArrayLike, F: ArrayLike, *, sources: Mapping[int, float] | None = None,
         flux: Mapping[int, float] | None = None, dt: float = 1e-3, steps: int = 100, diffusivity: float = 1.0,
         initial: ArrayLike | None = None, local: bool = False, laplacian: str = "auto",
         callback: Callable[[int, np.ndarray, np.ndarray], None] | None = None) -> SimpleNamespace: ...
def wave(V: ArrayLike, F: ArrayLike, *, sources: Mapping[int, float] | None = None,
         flux: Mapping[int, float] | None = None, impulses: Mapping[int, float] | None = None, dt: float = 1e-3,
         steps: int = 100, speed: float = 1.0, damping: float = 0.0, initial: ArrayLike | None = None,
         initial_velocity: ArrayLike | None = None, local: bool = False, laplacian: str = "auto",
         callback: Callable[[int, np.ndarray, np.ndarray], None] | None = None) -> SimpleNamespace: ...
def wave_energy(V: ArrayLike, F: ArrayLike, u: ArrayLike, ut: ArrayLike, speed: float = 1.0) -> float: ...
def fair(V: ArrayLike, F: ArrayLike, fixed: Union[ArrayLike, str, Sequence[str]], *, order: int = 2,
         regularize: bool = False, dt: float = 1.0, steps: int = 15, damping: float = 0.0,
         solver: str = "direct", laplacian: str = "auto") -> SimpleNamespace: ...
def interpolate(V: ArrayLike, F: ArrayLike, vertices: ArrayLike, values: ArrayLike, *, kind: str | None = None,
                method: str = "componentwise", g1: float = 0.0, g2: float = 1.0, solver: str = "direct",
                laplacian: str = "auto") -> np.ndarray: ...

class CorrectionResult:
    """A correction's arrays and the report of `meshpde correct --json` under its key names."""
    V: np.ndarray
    displacement: np.ndarray
    region: np.ndarray
    moved_vertices: int
    max_displacement: float
    region_vertices: int
    new_self_intersections: int
    time_ms: float
    method: str
    boundary: str
    dynamic: bool
    laplacian: str
    laplacian_reason: str
    relative_residual: float
    condition_estimate: float
    error_bound: float
    accuracy_warning: str | None
    region_warning: str | None
    handle_warning: str | None
    applied_fraction: float
    substeps: int
    intersection_action: str
    handles: int
    solver: str
    units: str
    image: dict[str, Any] | None
    def to_dict(self) -> dict[str, Any]: ...

def correct(V: ArrayLike, F: ArrayLike, vertices: ArrayLike | None = None, moves: Sequence[Move] | None = None, *,
            points: ArrayLike | None = None, handle_radius: float = -1.0, radius: float = 0.0,
            rings: int = 0, method: str = "fem", g1: float = 0.0, g2: float = 1.0, laplacian: str = "auto",
            stiffness: ArrayLike | None = None, dynamic: bool = False, steps: int = 50,
            mass: float | ArrayLike = 0.1, elasticity: float | ArrayLike = 0.9, viscosity: float | ArrayLike = 0.6, brushes: Sequence[str] | None = None,
            allow_intersections: bool = False, max_substeps: int = 8, image: Union[Path, tuple[ArrayLike, ArrayLike], None] = None, space: str = "lps",
            image_weight: float = 30.0, image_sigma: float = 1.0, search_radius: float = 3.0, cube: int = 0,
            passes: int = 4, solver: str = "auto", units: str = "mm", boundary: str = "smooth", caps: str = "labels",
            face_labels: ArrayLike | None = None) -> CorrectionResult: ...

class CorrectionSession:
    V: np.ndarray
    original: np.ndarray
    F: np.ndarray
    can_undo: bool
    can_redo: bool
    def __init__(self, V: ArrayLike, F: ArrayLike) -> None: ...
    def apply(self, vertices: ArrayLike | None = None, moves: Sequence[Move] | None = None, *,
              points: ArrayLike | None = None, handle_radius: float = -1.0, radius: float = 0.0, rings: int = 0,
              method: str = "fem", g1: float = 0.0, g2: float = 1.0, laplacian: str = "auto",
              stiffness: ArrayLike | None = None, dynamic: bool = False, steps: int = 50,
              mass: float | ArrayLike = 0.1, elasticity: float | ArrayLike = 0.9, viscosity: float | ArrayLike = 0.6, brushes: Sequence[str] | None = None,
              allow_intersections: bool = False, max_substeps: int = 8, image: Union[Path, tuple[ArrayLike, ArrayLike], None] = None,
              space: str = "lps", image_weight: float = 30.0, image_sigma: float = 1.0, search_radius: float = 3.0,
              cube: int = 0, passes: int = 4, solver: str = "auto", units: str = "mm", boundary: str = "smooth",
              caps: str = "labels", face_labels: ArrayLike | None = None) -> CorrectionResult: ...
    def undo(self) -> None: ...
    def redo(self) -> None: ...
    def new_self_intersections(self) -> int: ...

# --- stateful solvers --------------------------------------------------------------------
class PdeSession:
    """alpha u_tt - g1 lap(u) + g2 bilap(u) + g0 u = f by backward Euler on an active domain."""
    components: int
    values: np.ndarray
    velocities: np.ndarray
    constrained_vertices: np.ndarray
    reaction_forces: np.ndarray
    free_vertices: np.ndarray
    def __init__(self, V: ArrayLike, F: ArrayLike, components: int = 1, alpha: float = 0.0, b1: float = 1.0,
                 b2: float = 0.0, g0: float = 0.0, g1: float = 1.0, g2: float = 0.0, self_adjusting: bool = False,
                 grow_fraction: float = 1e-3, rest_value: float = 1e-6, rest_rate: float = 1e-4, rest_steps: int = 5,
                 seed_rings: int = 2, max_free: int = 0, tolerance: float = ..., max_iterations: int = ...) -> None: ...
    def set_values(self, u: ArrayLike, as_rest: bool = True) -> None: ...
    def set_velocities(self, v: ArrayLike) -> None: ...
    def constrain(self, vertex: int, value: Union[float, ArrayLike]) -> None: ...
    def release(self, vertex: int) -> None: ...
    def activate(self, vertices: ArrayLike) -> None: ...
    def activate_all(self) -> None: ...
    def activate_rings(self, vertex: int, rings: int) -> None: ...
    def deactivate_all(self) -> None: ...
    def step(self, dt: float, f: ArrayLike | None = None) -> dict[str, Any]: ...
    def solve_steady(self, f: ArrayLike | None = None) -> dict[str, Any]: ...

class HapticSession:
    touching: bool
    contact_vertex: int
    running: bool
    latest_force: np.ndarray
    displacement: np.ndarray
    active_vertices: int
    misses: int
    def __init__(self, V: ArrayLike, F: ArrayLike, influence: float = 0.0, stiffness: float = 1.0, mass: float = 1e-2,
                 damping: float = 0.2, stiffness_damping: float = 1e-3, domain_tolerance: float = 5e-2,
                 rate_hz: float = 1000.0) -> None: ...
    def touch(self, vertex: int) -> None: ...
    def touch_point(self, point: ArrayLike) -> None: ...
    def move_probe(self, offset: ArrayLike) -> None: ...
    def release(self) -> None: ...
    def step(self, dt: float) -> np.ndarray: ...
    def start(self) -> None: ...
    def stop(self) -> None: ...
    def log(self) -> dict[str, np.ndarray]: ...

class DragSession:
    handles: np.ndarray
    region: np.ndarray
    basis: np.ndarray
    factorizations: int
    boundary: str
    handle_radius: float
    readings: list[list[tuple[int, float]]]
    def __init__(self, V: ArrayLike, F: ArrayLike, handles: ArrayLike | None = None, radius: float = 0.0,
                 rings: int = 0, g1: float = 0.0, g2: float = 1.0, boundary: str = "smooth", margin: bool = False,
                 inner_margin: bool = False, points: ArrayLike | None = None,
                 handle_radius: float | None = None) -> None: ...
    def displacements(self, handle_displacements: ArrayLike) -> np.ndarray: ...
    def positions(self, handle_displacements: ArrayLike) -> np.ndarray: ...
    def forces(self, handle_displacements: ArrayLike) -> np.ndarray: ...
    def add_handle(self, vertex: int) -> None: ...
    def grow(self, rings: int = 1) -> None: ...
    def shrink(self, rings: int = 1) -> None: ...

class InterpolationSolver:
    """Interpolation with a kept factor: set_value / remove / clear, then solve()."""
    num_constraints: int
    vertices: list[int]
    factorizations: int
    reused_orders: int
    changed_constraints: int
    max_changes: int
    def __init__(self, V: ArrayLike, F: ArrayLike, kind: str = "scalar", g1: float = 0.0, g2: float = 1.0,
                 laplacian: str = "auto") -> None: ...
    def set_value(self, vertex: int, value: float | ArrayLike) -> None: ...
    def remove(self, vertex: int) -> None: ...
    def clear(self) -> None: ...
    def solve(self) -> np.ndarray: ...

class GlobalBilaplacianSolver:
    multigrid_builds: int
    factorizations: int
    def __init__(self, V: ArrayLike, F: ArrayLike, free: ArrayLike, g1: float = 0.0, g2: float = 1.0,
                 tolerance: float = 1e-8, max_iterations: int = 1000, preconditioner: str = "auto") -> None: ...
    def solve(self, u: ArrayLike, warm_start: bool = False) -> tuple[np.ndarray, dict[str, Any]]: ...

# --- interop -------------------------------------------------------------------------------
def from_vtk(polydata: Any) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]: ...
def to_vtk(V: ArrayLike, F: ArrayLike, fields: Mapping[str, ArrayLike] | None = None) -> Any: ...
