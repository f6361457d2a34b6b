"""VTK's Python package and meshio, through plain arrays."""
import numpy as np
import pytest

import meshpde


def test_vtk_round_trip_keeps_point_data(tmp_path):
    vtk = pytest.importorskip("vtk", reason="python3-vtk9 not installed")
    V, F = meshpde.generate.icosphere(2)
    fields = {"u": V[:, 0] ** 2, "d": 0.5 * V}
    poly = meshpde.to_vtk(V, F, fields)
    assert isinstance(poly, vtk.vtkPolyData) and poly.GetNumberOfCells() == len(F)
    V2, F2, f2 = meshpde.from_vtk(poly)
    assert np.array_equal(V2, V) and np.array_equal(F2, F)
    assert np.array_equal(f2["u"], fields["u"]) and np.array_equal(f2["d"], fields["d"])
    # and through a file written by VTK's own writer, read by meshpde
    if meshpde.has_medical:
        w = vtk.vtkXMLPolyDataWriter()
        w.SetFileName(str(tmp_path / "v.vtp"))
        w.SetInputData(poly)
        assert w.Write() == 1
        V3, F3, f3 = meshpde.read_mesh(tmp_path / "v.vtp")
        assert np.array_equal(V3, V) and np.array_equal(F3, F) and np.array_equal(f3["u"], fields["u"])


def test_vtk_quads_are_triangulated():
    vtk = pytest.importorskip("vtk", reason="python3-vtk9 not installed")
    src = vtk.vtkPlaneSource()
    src.SetResolution(3, 2)
    src.Update()
    V, F, _ = meshpde.from_vtk(src.GetOutput())
    assert len(V) == 12 and len(F) == 12
    assert meshpde.info(V, F)["area"] == pytest.approx(1.0)


def test_from_vtk_refuses_other_objects():
    pytest.importorskip("vtk", reason="python3-vtk9 not installed")
    with pytest.raises(TypeError):
        meshpde.from_vtk(np.zeros((3, 3)))


def test_meshio_round_trips_through_arrays(tmp_path):
    meshio = pytest.importorskip("meshio", reason="python3-meshio not installed")
    V, F = meshpde.generate.icosphere(2)
    H = meshpde.curvature(V, F)
    meshio.write(tmp_path / "m.vtu", meshio.Mesh(V, [("triangle", F)], point_data={"H": H}))
    m = meshio.read(tmp_path / "m.vtu")
    assert np.array_equal(m.points, V) and np.array_equal(m.cells_dict["triangle"], F)
    assert np.array_equal(m.point_data["H"], H)
    # a file meshio writes, meshpde reads (and the other way)
    meshio.write(tmp_path / "m.ply", meshio.Mesh(V, [("triangle", F)]))
    V2, F2, _ = meshpde.read_mesh(tmp_path / "m.ply")
    assert np.allclose(V2, V) and np.array_equal(F2, F)
    meshpde.write_mesh(tmp_path / "o.obj", V, F)
    m2 = meshio.read(tmp_path / "o.obj")
    assert np.allclose(m2.points, V) and np.array_equal(m2.cells_dict["triangle"], F)


def test_the_python_benchmark_runs_and_reports_its_baselines():
    # Timings are not asserted (shared machines); the script must run and report both sides.
    import json
    import os
    import pathlib
    import subprocess
    import sys
    script = pathlib.Path(__file__).parents[2] / "bench" / "python" / "bench_python.py"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    out = subprocess.run([sys.executable, str(script), "--quick", "--json"], capture_output=True, text=True,
                         timeout=600, env=env)
    assert out.returncode == 0, out.stderr
    j = json.loads(out.stdout)
    for key in ["python_poke_step_overhead_us", "python_poke_step_cpp_baseline_p50_us",
                "python_stiffness_s_41k", "python_stiffness_cpp_baseline_s_41k"]:
        assert key in j and j[key] == j[key], key  # present and not NaN
    assert j["python_poke_step_cpp_baseline_p50_us"] > 0 and j["python_stiffness_cpp_baseline_s_41k"] > 0
