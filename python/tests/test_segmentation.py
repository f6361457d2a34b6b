"""Segmentations in and out (io/segmentation_io.h, apps/segment_surface.h): a .seg.nrrd
with several segments and layers written by these tests from the aorta's level set,
extracted, corrected and voxelized back, by Python and by the tool."""
import json
import subprocess

import numpy as np
import pytest

import meshpde

if not meshpde.has_medical:
    pytest.skip("built without meshpde::medical", allow_module_level=True)


@pytest.fixture(scope="module")
def case(tmp_path_factory, data):
    """A .seg.nrrd on the aorta angiography's grid: the aorta (label 1) and a shell around
    it (label 2) in layer 0, a box (label 1) in layer 1; and a plain label map of the aorta."""
    phi, A = meshpde.read_volume(data("aorta-levelset.mha"))
    labels = np.zeros(phi.shape + (2,), np.int32)
    labels[..., 0][phi < 0] = 1
    labels[..., 0][(phi > 1.0) & (phi < 2.0)] = 2
    labels[80:100, 150:200, 5:15, 1] = 1
    segments = [dict(name="aorta", id="Segment_1", label=1, layer=0, color=(0.8, 0.1, 0.1)),
                dict(name="shell", id="Segment_2", label=2, layer=0, color=(0.9, 0.9, 0.3)),
                dict(name="box", id="Segment_3", label=1, layer=1, color=(0.1, 0.3, 0.9))]
    root = tmp_path_factory.mktemp("segmentation")
    seg = root / "case.seg.nrrd"
    meshpde.write_segmentation(seg, labels, A, segments)
    nii = root / "aorta-labels.nii.gz"
    meshpde.write_segmentation(nii, labels[..., 0] == 1, A)
    return dict(root=root, seg=seg, nii=nii, labels=labels, affine=A, segments=segments)


def run(cli_path, *args):
    return subprocess.run([cli_path, *map(str, args)], capture_output=True, text=True, timeout=300)


def test_a_segmentation_reads_back_as_written(case):
    labels, A, segments = meshpde.read_segmentation(case["seg"])
    assert labels.dtype == np.int32 and labels.shape == case["labels"].shape
    assert np.array_equal(labels, case["labels"]) and np.allclose(A, case["affine"])
    assert [(s["name"], s["label"], s["layer"]) for s in segments] == [("aorta", 1, 0), ("shell", 2, 0), ("box", 1, 1)]
    assert segments[2]["color"] == pytest.approx((0.1, 0.3, 0.9), abs=1e-6)
    one, B, table = meshpde.read_segmentation(case["nii"])
    assert one.ndim == 3 and np.array_equal(one, case["labels"][..., 0] == 1) and np.allclose(B, A, atol=1e-5)
    assert [s["name"] for s in table] == ["label 1"]


def test_info_lists_the_segments(case, cli):
    info = cli("info", case["seg"], "--json", json_out=True)
    assert info["kind"] == "segmentation" and info["layers"] == 2 and info["format"] == "seg.nrrd"
    assert [s["name"] for s in info["segments"]] == ["aorta", "shell", "box"]
    assert info["segments"][0]["voxels"] == int((case["labels"][..., 0] == 1).sum())
    assert info["segments"][2]["voxels"] == 20 * 50 * 10


def test_extract_needs_a_segment_among_several_and_keeps_it_in_the_field_data(case, cli, cli_path, tmp_path, data):
    r = run(cli_path, "extract", case["seg"], "-o", tmp_path / "x.vtp")
    assert r.returncode == 1 and "holds 3 segments" in r.stderr and "'shell'" in r.stderr and "'box'" in r.stderr
    out = tmp_path / "aorta.vtp"
    report = cli("extract", case["seg"], "--segment", "aorta", "-o", out, "--json", json_out=True)
    assert report["closed"] and report["segment"]["label"] == 1 and report["space"] == "LPS"
    assert report["surface_volume_mm3"] == pytest.approx(report["voxel_volume_mm3"], rel=0.05)
    # What another VTK program sees: the points in LPS mm, the segment in the field data.
    vtk = pytest.importorskip("vtk")
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(out))
    reader.Update()
    pd = reader.GetOutput()
    fd = pd.GetFieldData()
    assert fd.GetAbstractArray("Segment_Name").GetValue(0) == "aorta"
    assert fd.GetAbstractArray("SPACE").GetValue(0) == "LPS"
    assert fd.GetArray("Segment_Color").GetNumberOfComponents() == 3
    V, F, info = meshpde.extract_surface(case["seg"], "aorta")
    assert pd.GetNumberOfPoints() == len(V) and info["voxels"] == report["voxels"]
    # The registered vmtk mesh is in RAS: flipped to LPS it lies on this surface.
    ref, G, _ = meshpde.read_mesh(data("aorta-closed-6k.vtp"))
    assert meshpde.hausdorff_distance(V, F, ref * [-1, -1, 1], G) < 1.0


def test_extract_from_arrays_equals_extract_from_the_file(case):
    V, F, info = meshpde.extract_surface(case["seg"], "shell", smoothing=0.3)
    W, G, other = meshpde.extract_surface(case["labels"][..., 0], 2, affine=case["affine"], smoothing=0.3)
    assert np.array_equal(F, G) and np.abs(V - W).max() < 1e-9
    assert info["label"] == other["label"] == 2
    with pytest.raises(meshpde.InputError, match="affine"):
        meshpde.extract_surface(case["labels"][..., 0], 1)
    with pytest.raises(meshpde.InputError, match="no segment 'liver'"):
        meshpde.extract_surface(case["seg"], "liver")


def test_round_trip_without_a_correction(case, cli, tmp_path):
    surface = tmp_path / "aorta.vtp"
    cli("extract", case["seg"], "--segment", "aorta", "-o", surface)
    # No displacement: every voxel of the segment decided again: Dice >= 0.98, the other
    # segments and the other layer bit for bit.
    out = tmp_path / "full.seg.nrrd"
    r = cli("voxelize", surface, "--reference", case["seg"], "-o", out, "--json", json_out=True)
    assert not r["partial"] and r["segment"]["name"] == "aorta"
    labels, _, _ = meshpde.read_segmentation(out)
    before = case["labels"][..., 0] == 1
    after = labels[..., 0] == 1
    dice = 2 * (before & after).sum() / (before.sum() + after.sum())
    assert dice >= 0.98
    assert np.array_equal(labels[..., 1], case["labels"][..., 1])
    shell = case["labels"][..., 0] == 2
    assert np.array_equal(labels[..., 0][shell], case["labels"][..., 0][shell])
    # A surface that carries a zero displacement: not one voxel changes.
    V, F, fields = meshpde.read_mesh(surface)
    zero = tmp_path / "zero.vtp"
    meshpde.write_mesh(zero, V, F, {"displacement": np.zeros_like(V)})
    out2 = tmp_path / "same.seg.nrrd"
    r2 = cli("voxelize", zero, "--reference", case["seg"], "--segment", "aorta", "-o", out2, "--json",
             json_out=True)
    assert r2["partial"] and r2["added"] == r2["removed"] == 0
    assert np.array_equal(meshpde.read_segmentation(out2)[0], case["labels"])


def test_round_trip_on_thick_slices(data, tmp_path, cli):
    # The aorta on 3 x 3 x 10 mm voxels (a thick-slice CT's segmentation): the default
    # smoothing still gives Dice >= 0.98 when every voxel is decided again.
    ndimage = pytest.importorskip("scipy.ndimage")
    phi, A = meshpde.read_volume(data("aorta-levelset.mha"))
    spacing = np.linalg.norm(A[:3, :3], axis=0)
    coarse = np.array([3.0, 3.0, 10.0])
    dims = np.floor((np.array(phi.shape) - 1) * spacing / coarse).astype(int) + 1
    B = A.copy()
    B[:3, :3] = A[:3, :3] / spacing * coarse
    grid = np.indices(dims).reshape(3, -1) * (coarse / spacing)[:, None]  # in the fine grid's voxels
    labels = (ndimage.map_coordinates(phi, grid, order=1) < 0).reshape(dims).astype(np.int32)
    seg = tmp_path / "thick.seg.nrrd"
    meshpde.write_segmentation(seg, labels, B, [dict(name="aorta", label=1)])
    surface = tmp_path / "thick.vtp"
    cli("extract", seg, "-o", surface)
    out = tmp_path / "back.seg.nrrd"
    cli("voxelize", surface, "--reference", seg, "--full", "-o", out)
    back = meshpde.read_segmentation(out)[0] == 1
    dice = 2 * (back & (labels == 1)).sum() / (back.sum() + (labels == 1).sum())
    print(f"thick-slice round trip: {labels.sum()} voxels, Dice {dice:.4f}")
    assert dice >= 0.98


def test_after_a_correction_only_voxels_near_the_handle_change(case, cli, tmp_path):
    surface = tmp_path / "aorta.vtp"
    cli("extract", case["seg"], "--segment", "aorta", "-o", surface)
    V, F, _ = meshpde.read_mesh(surface)
    handle, radius = 2500, 8.0
    fixed = tmp_path / "fixed.vtp"
    cli("correct", surface, "--vertex", handle, "--move", "normal:-2", "--radius", radius, "-o", fixed)
    out = tmp_path / "fixed.seg.nrrd"
    r = cli("voxelize", fixed, "--reference", case["seg"], "-o", out, "--json", json_out=True)
    assert r["partial"] and r["moved_vertices"] > 10 and r["removed"] > 0
    labels, A, segments = meshpde.read_segmentation(out)
    changed = np.argwhere(labels != case["labels"])
    assert len(changed) == r["added"] + r["removed"] > 0
    voxel = np.linalg.norm(A[:3, :3], axis=0).max()
    lps = changed[:, :3] @ A[:3, :3].T + A[:3, 3]
    assert np.linalg.norm(lps - V[handle], axis=1).max() <= radius + 2 * voxel
    assert (changed[:, 3] == 0).all()  # layer 1 untouched
    # The header as the input had it, the segments' extents still holding their voxels.
    assert [s["name"] for s in segments] == ["aorta", "shell", "box"]


def test_python_voxelize_equals_the_tool(case, tmp_path, cli):
    V, F, info = meshpde.extract_surface(case["nii"])
    res = meshpde.correct(V, F, [1500], ["normal:1.5"], radius=7.0)
    labels, A, segments, report = meshpde.voxelize(res.V, F, case["nii"], displacement=res.displacement,
                                                   output=tmp_path / "py.nii.gz")
    assert report["partial"] and report["added"] > 0 and report["reference_is_image"] is False
    meshpde.write_mesh(tmp_path / "fixed.vtp", res.V, F, {"displacement": res.displacement})
    cli("voxelize", tmp_path / "fixed.vtp", "--reference", case["nii"], "-o", tmp_path / "cli.nii.gz")
    assert np.array_equal(meshpde.read_segmentation(tmp_path / "cli.nii.gz")[0], labels)
    assert np.array_equal(meshpde.read_segmentation(tmp_path / "py.nii.gz")[0], labels)


def test_an_image_as_reference_gets_a_new_label_map_on_its_grid(case, data, tmp_path):
    V, F, _ = meshpde.extract_surface(case["seg"], "aorta")
    labels, A, segments, report = meshpde.voxelize(V, F, data("aorta-mra.mha"), 3, output=tmp_path / "new.nrrd")
    assert report["reference_is_image"] and report["label"] == 3
    mra, B = meshpde.read_volume(data("aorta-mra.mha"))
    assert labels.shape == mra.shape and np.allclose(A, B)
    assert set(np.unique(labels)) == {0, 3}
    again, _, table = meshpde.read_segmentation(tmp_path / "new.nrrd")
    assert np.array_equal(again, labels) and table[0]["label"] == 3


def test_units_and_frames_of_the_surface(case, cli, tmp_path):
    # The same surface written in RAS centimetres voxelizes to the same voxels.
    mm = tmp_path / "mm.vtp"
    cli("extract", case["seg"], "--segment", "aorta", "-o", mm)
    cm = tmp_path / "cm.vtp"
    r = cli("extract", case["seg"], "--segment", "aorta", "-o", cm, "--units", "cm", "--space", "ras", "--json",
            json_out=True)
    assert r["units"] == "cm" and r["space"] == "RAS"
    V1, _, _ = meshpde.read_mesh(mm)
    V2, _, _ = meshpde.read_mesh(cm)
    assert np.abs(V2 * 10 * [-1, -1, 1] - V1).max() < 1e-9
    a = cli("voxelize", mm, "--reference", case["seg"], "-o", tmp_path / "a.seg.nrrd", "--json", json_out=True)
    b = cli("voxelize", cm, "--reference", case["seg"], "--units", "cm", "-o", tmp_path / "b.seg.nrrd", "--json",
            json_out=True)
    assert b["units"] == "cm" and b["space"] == "RAS"  # the file's SPACE tag
    assert np.array_equal(meshpde.read_segmentation(tmp_path / "a.seg.nrrd")[0],
                          meshpde.read_segmentation(tmp_path / "b.seg.nrrd")[0])
    assert a["added"] == b["added"]


def test_bad_segmentation_input_is_refused_in_words(case, cli_path, tmp_path):
    open_mesh = tmp_path / "open.ply"
    V, F, _ = meshpde.extract_surface(case["nii"])
    meshpde.write_mesh(open_mesh, V, F[:-5])
    r = run(cli_path, "voxelize", open_mesh, "--reference", case["nii"], "-o", tmp_path / "o.nii.gz")
    assert r.returncode == 1 and "not closed" in r.stderr
    assert not (tmp_path / "o.nii.gz").exists()
    r = run(cli_path, "extract", tmp_path / "missing.seg.nrrd", "-o", tmp_path / "m.vtp")
    assert r.returncode == 1 and "missing.seg.nrrd" in r.stderr
    with pytest.raises(meshpde.InputError, match="whole numbers"):
        meshpde.write_segmentation(tmp_path / "f.nii", np.full((2, 2, 2), 0.5), np.eye(4))
