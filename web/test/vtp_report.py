"""What a saved .vtp holds, read back with VTK (not with meshpde's own reader), as JSON.

Usage: /usr/bin/python3 vtp_report.py SAVED.vtp [ORIGINAL.vtp]

Prints the points' type and bounds, the SPACE field-data tag, every point and cell array (type,
components), and for each 3-component point array whose name says normals, the largest
angle (degrees) between it and the area-weighted normals of the saved surface (sign
matched), over all vertices and over the 99.9 % best; with ORIGINAL, the largest angle
between the saved normals and the original file's (stale normals would be these).
"""
import json
import sys

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader


def read(path):
    r = vtkXMLPolyDataReader()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput()


def normals_of(P, F):
    n = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    N = np.zeros_like(P)
    for k in range(3):
        np.add.at(N, F[:, k], n)
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)


def angles(a, b):
    a = a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-300)
    b = b / np.maximum(np.linalg.norm(b, axis=1, keepdims=True), 1e-300)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=1), -1, 1)))


def main():
    pd = read(sys.argv[1])
    original = read(sys.argv[2]) if len(sys.argv) > 2 else None
    P = vtk_to_numpy(pd.GetPoints().GetData()).astype(np.float64)
    F = vtk_to_numpy(pd.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    out = {"points": pd.GetNumberOfPoints(), "points_type": pd.GetPoints().GetData().GetDataTypeAsString(),
           "bounds": {"min": P.min(axis=0).tolist(), "max": P.max(axis=0).tolist()},
           "space": None, "point_arrays": {}, "cell_arrays": {}, "normals": {}}
    fd = pd.GetFieldData()
    for i in range(fd.GetNumberOfArrays()):
        a = fd.GetAbstractArray(i)
        if a.GetName() == "SPACE":
            out["space"] = a.GetValue(0)
    fresh = normals_of(P, F)
    for data, key in ((pd.GetPointData(), "point_arrays"), (pd.GetCellData(), "cell_arrays")):
        for i in range(data.GetNumberOfArrays()):
            a = data.GetArray(i)
            out[key][a.GetName()] = {"type": a.GetDataTypeAsString(), "components": a.GetNumberOfComponents()}
            if key == "point_arrays" and "normal" in a.GetName().lower() and a.GetNumberOfComponents() == 3:
                N = vtk_to_numpy(a).astype(np.float64)
                s = 1.0 if np.sum(N * fresh) >= 0 else -1.0
                err = angles(N, s * fresh)
                report = {"max_deg": float(err.max()), "p999_deg": float(np.quantile(err, 0.999))}
                if original is not None:
                    old = original.GetPointData().GetArray(a.GetName())
                    if old is not None:
                        report["max_deg_to_original"] = float(angles(N, vtk_to_numpy(old).astype(np.float64)).max())
                out["normals"][a.GetName()] = report
    if pd.GetPointData().GetArray("displacement") is not None and original is not None:
        D = vtk_to_numpy(pd.GetPointData().GetArray("displacement")).astype(np.float64)
        P0 = vtk_to_numpy(original.GetPoints().GetData()).astype(np.float64)
        out["displacement_error"] = float(np.abs(P - P0 - D).max())
        out["displacement_max"] = float(np.linalg.norm(D, axis=1).max())
    print(json.dumps(out))


if __name__ == "__main__":
    main()
