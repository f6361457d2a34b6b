"""Interop with VTK's Python package (Debian python3-vtk9) and meshio.

``from_vtk(polydata) -> (V, F, fields)`` and ``to_vtk(V, F, fields=None) -> vtkPolyData``
carry point-data arrays both ways (1 component as (n,), k components as (n, k)).
meshio needs nothing special: ``meshio.Mesh(V, [("triangle", F)], point_data=fields)``
and back ``(m.points, m.cells_dict["triangle"], m.point_data)`` are plain arrays.
"""

from __future__ import annotations

import numpy as np


def _vtk():
    try:
        import vtk
        from vtk.util import numpy_support
    except ImportError as e:  # pragma: no cover - depends on the machine
        raise ImportError("meshpde.from_vtk/to_vtk need VTK's Python package (Debian: python3-vtk9)") from e
    return vtk, numpy_support


def from_vtk(polydata):
    """(V, F, fields) of a vtkPolyData (or any vtkDataSet with a GetPolys()).

    Polygons with more than three corners are fan-triangulated (VTK's vtkTriangleFilter);
    lines and vertices are ignored. Point-data arrays become fields.
    """
    vtk, ns = _vtk()
    if not isinstance(polydata, vtk.vtkPolyData):
        raise TypeError(f"from_vtk: expected a vtkPolyData, got {type(polydata).__name__}")
    tri = vtk.vtkTriangleFilter()
    tri.SetInputData(polydata)
    tri.PassLinesOff()
    tri.PassVertsOff()
    tri.Update()
    out = tri.GetOutput()
    if out.GetNumberOfPoints() == 0:
        raise ValueError("from_vtk: the polydata has no points")
    V = ns.vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    conn = ns.vtk_to_numpy(out.GetPolys().GetConnectivityArray())
    F = conn.reshape(-1, 3).astype(np.int32)
    fields = {}
    pd = out.GetPointData()
    for k in range(pd.GetNumberOfArrays()):
        a = pd.GetArray(k)
        if a is None or a.GetName() is None:
            continue
        fields[a.GetName()] = ns.vtk_to_numpy(a).astype(np.float64)
    return V, F, fields


def to_vtk(V, F, fields=None):
    """A vtkPolyData with triangles F over points V and the fields as point data."""
    vtk, ns = _vtk()
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"V: expected an (n, 3) array, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"F: expected an (m, 3) array, got shape {F.shape}")
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise IndexError(f"F: vertex index out of range for {len(V)} vertices")
    points = vtk.vtkPoints()
    points.SetData(ns.numpy_to_vtk(V, deep=True))
    cells = vtk.vtkCellArray()
    offsets = np.arange(0, 3 * len(F) + 1, 3, dtype=np.int64)
    cells.SetData(ns.numpy_to_vtk(offsets, deep=True, array_type=vtk.VTK_ID_TYPE),
                  ns.numpy_to_vtk(F.ravel(), deep=True, array_type=vtk.VTK_ID_TYPE))
    poly = vtk.vtkPolyData()
    poly.SetPoints(points)
    poly.SetPolys(cells)
    for name, values in (fields or {}).items():
        values = np.ascontiguousarray(values, dtype=np.float64)
        if values.shape[0] != len(V):
            raise ValueError(f"fields['{name}']: expected {len(V)} rows, got {values.shape[0]}")
        a = ns.numpy_to_vtk(values, deep=True)
        a.SetName(name)
        poly.GetPointData().AddArray(a)
    return poly
