"""A generated model turned into what SimVascular writes: centimetres, Float32 points,
the face labels as ModelFaceID (wall 1, caps 2, 3, ...) and a Normals point array.

Usage: /usr/bin/python3 simvascular_model.py IN_MM.vtp OUT_CM.vtp

IN_MM.vtp: a capped surface in millimetres with CellEntityIds (meshpde generate
bifurcation --caps). Prints JSON: the points as written (cm, flat x y z), the cap
vertices (on a face labelled 2 or more) and, for each cap, the wall vertex nearest its
centre (where a drag tests the cap's hold).
"""
import json
import sys

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader, vtkXMLPolyDataWriter


def main():
    r = vtkXMLPolyDataReader()
    r.SetFileName(sys.argv[1])
    r.Update()
    pd = r.GetOutput()
    P = vtk_to_numpy(pd.GetPoints().GetData()).astype(np.float64)
    F = vtk_to_numpy(pd.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    labels = vtk_to_numpy(pd.GetCellData().GetArray("CellEntityIds")).astype(np.int32)
    in_cm = np.ascontiguousarray(P / 10.0, dtype=np.float32)
    points = vtkPoints()
    points.SetData(numpy_to_vtk(in_cm, deep=True))
    pd.SetPoints(points)
    ids = numpy_to_vtk(labels, deep=True)
    ids.SetName("ModelFaceID")
    pd.GetCellData().RemoveArray("CellEntityIds")
    pd.GetCellData().AddArray(ids)
    normals = vtkPolyDataNormals()
    normals.SetInputData(pd)
    normals.SplittingOff()
    normals.ConsistencyOff()
    normals.ComputeCellNormalsOff()
    normals.Update()
    out = normals.GetOutput()
    w = vtkXMLPolyDataWriter()
    w.SetFileName(sys.argv[2])
    w.SetInputData(out)
    if not w.Write():
        sys.exit(f"could not write {sys.argv[2]}")
    caps = sorted(set(F[labels >= 2].ravel().tolist()))
    wall = np.setdiff1d(np.arange(len(P)), caps)
    near = []
    for label in sorted(set(labels.tolist()) - {1}):
        centre = P[np.unique(F[labels == label].ravel())].mean(axis=0)
        near.append(int(wall[np.argmin(np.linalg.norm(P[wall] - centre, axis=1))]))
    print(json.dumps({"points": in_cm.astype(np.float64).ravel().tolist(), "caps": caps, "wall_near_cap": near}))


if __name__ == "__main__":
    main()
