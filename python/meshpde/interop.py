"""Interop with VTK's Python package (Debian python3-vtk9) and meshio.

``from_vtk(polydata) -> (V, F, fields)`` and ``to_vtk(V, F, fields=None, cells=None) -> vtkPolyData``
carry point-data arrays (1 component as (n,), k components as (n, k)), cell-data
arrays (``fields.cells``, a row per triangle) and 3D Slicer's SPACE tag both ways, each
array in its own type (an Int32 ``ModelFaceID`` stays int32).
meshio needs nothing special: ``meshio.Mesh(V, [("triangle", F)], point_data=fields)``
and back ``(m.points, m.cells_dict["triangle"], m.point_data)`` are plain arrays.
"""

from __future__ import annotations

import numpy as np

from ._meshpde import InputError, OutOfRangeError


def _vtk():
    try:
        import vtk
        from vtk.util import numpy_support
    except ImportError as e:  # pragma: no cover - depends on the machine
        raise ImportError("meshpde.from_vtk/to_vtk need VTK's Python package (Debian: python3-vtk9)") from e
    return vtk, numpy_support


def from_vtk(polydata):
    """(V, F, fields) of a vtkPolyData, as :func:`meshpde.read_mesh` gives them.

    Polygons with more than three corners are fan-triangulated (VTK's vtkTriangleFilter,
    their cell data repeated per triangle); lines and vertices are ignored. Point-data
    arrays become the fields, cell-data arrays ``fields.cells``, a string array SPACE
    ``fields.space``, other field data ``fields.field_data``; each keeps its type.
    """
    from . import MeshFields
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
        raise InputError("from_vtk: the polydata has no points")
    V = ns.vtk_to_numpy(out.GetPoints().GetData()).astype(np.float64)
    conn = ns.vtk_to_numpy(out.GetPolys().GetConnectivityArray())
    F = conn.reshape(-1, 3).astype(np.int32)
    def arrays(data):
        out_arrays = {}
        for k in range(data.GetNumberOfArrays()):
            a = data.GetArray(k)
            if a is None or a.GetName() is None:
                continue
            out_arrays[a.GetName()] = np.array(ns.vtk_to_numpy(a))
        return out_arrays

    space, field_data = None, {}
    fd = polydata.GetFieldData()
    for k in range(fd.GetNumberOfArrays()):
        a = fd.GetAbstractArray(k)
        if a is None or a.GetName() is None:
            continue
        if isinstance(a, vtk.vtkStringArray):
            value = a.GetValue(0) if a.GetNumberOfValues() else ""
            if a.GetName() == "SPACE":
                space = "RAS" if "RAS" in value else "LPS" if "LPS" in value else None
            else:
                field_data[a.GetName()] = value
        elif isinstance(a, vtk.vtkDataArray):
            values = np.array(ns.vtk_to_numpy(a))
            field_data[a.GetName()] = values.ravel() if values.ndim == 2 and values.shape[0] == 1 else values
    return V, F, MeshFields(arrays(out.GetPointData()), arrays(out.GetCellData()), space, field_data)


def to_vtk(V, F, fields=None, cells=None):
    """A vtkPolyData with triangles F over points V, the fields as point data and
    ``cells`` (default: ``fields.cells`` of a :class:`meshpde.MeshFields`) as cell data,
    each array in its dtype; a MeshFields' space becomes the SPACE field-data tag."""
    vtk, ns = _vtk()
    space = getattr(fields, "space", None)
    field_data = getattr(fields, "field_data", {}) or {}
    if cells is None:
        cells = getattr(fields, "cells", None)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InputError(f"V: expected an (n, 3) array, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise InputError(f"F: expected an (m, 3) array, got shape {F.shape}")
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise OutOfRangeError(f"F: vertex index out of range for {len(V)} vertices")
    points = vtk.vtkPoints()
    points.SetData(ns.numpy_to_vtk(V, deep=True))
    polys = vtk.vtkCellArray()
    offsets = np.arange(0, 3 * len(F) + 1, 3, dtype=np.int64)
    polys.SetData(ns.numpy_to_vtk(offsets, deep=True, array_type=vtk.VTK_ID_TYPE),
                  ns.numpy_to_vtk(F.ravel(), deep=True, array_type=vtk.VTK_ID_TYPE))
    poly = vtk.vtkPolyData()
    poly.SetPoints(points)
    poly.SetPolys(polys)

    def vtk_array(name, values, rows, what):
        values = np.asarray(values)
        if values.dtype == bool:
            values = values.astype(np.uint8)
        elif values.dtype.kind not in "iuf":
            values = values.astype(np.float64)
        values = np.ascontiguousarray(values)
        if values.shape[:1] != (rows,):
            raise InputError(f"{what}['{name}']: expected {rows} rows, got {values.shape[:1]}")
        a = ns.numpy_to_vtk(values, deep=True)
        a.SetName(name)
        return a

    for name, values in (fields or {}).items():
        poly.GetPointData().AddArray(vtk_array(name, values, len(V), "fields"))
    for name, values in (cells or {}).items():
        poly.GetCellData().AddArray(vtk_array(name, values, len(F), "cells"))
    tags = dict(field_data)
    if space:
        tags["SPACE"] = space
    for name, value in tags.items():
        if isinstance(value, str):
            s = vtk.vtkStringArray()
            s.SetName(name)
            s.InsertNextValue(value)
            poly.GetFieldData().AddArray(s)
        else:
            value = np.atleast_2d(np.asarray(value))
            poly.GetFieldData().AddArray(vtk_array(name, value, value.shape[0], "field_data"))
    return poly
