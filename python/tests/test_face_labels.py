"""Face labels, caps and units of CFD models (SimVascular, VMTK) through Python: cell
arrays and array types kept by every path, caps held by corrections, a model in
centimetres recognised."""
import warnings

import numpy as np
import pytest

import meshpde
import meshpde.batch

if not meshpde.has_medical:
    pytest.skip("built without meshpde::medical", allow_module_level=True)


@pytest.fixture(scope="module")
def pipe(data):
    return data("simvascular-pipe-capped-5k.vtp")


def test_read_mesh_gives_the_cell_arrays_and_the_types(pipe, tmp_path):
    V, F, fields = meshpde.read_mesh(pipe)
    assert isinstance(fields, meshpde.MeshFields) and isinstance(fields, dict)
    assert fields["GlobalNodeID"].dtype == np.int32
    cells = fields.cells
    assert set(cells) == {"ModelFaceID", "ModelRegionID", "GlobalElementID", "Normals"}
    assert cells["ModelFaceID"].dtype == np.int32 and cells["ModelFaceID"].shape == (len(F),)
    assert cells["Normals"].dtype == np.float32 and cells["Normals"].shape == (len(F), 3)
    assert set(np.unique(cells["ModelFaceID"])) == {1, 2, 3}
    for suffix in (".vtp", ".vtk"):
        out = tmp_path / f"again{suffix}"
        meshpde.write_mesh(out, V, F, fields)
        W, G, back = meshpde.read_mesh(out)
        assert np.array_equal(G, F) and np.allclose(W, V)
        for name, values in cells.items():
            assert back.cells[name].dtype == values.dtype and np.array_equal(back.cells[name], values), name
        assert back["GlobalNodeID"].dtype == np.int32 and np.array_equal(back["GlobalNodeID"], fields["GlobalNodeID"])
    with pytest.warns(UserWarning, match="cell data array"):
        meshpde.write_mesh(tmp_path / "lost.ply", V, F, fields)


@pytest.mark.parametrize("command", ["correct", "fair"])
def test_the_tools_correct_and_fair_keep_every_array_and_type(pipe, tmp_path, cli, command):
    V, F, fields = meshpde.read_mesh(pipe)
    out = tmp_path / f"{command}.vtp"
    if command == "correct":
        cli("correct", pipe, "--units", "cm", "--vertex", 202, "--move", "normal:3", "--radius", 12, "-o", out)
    else:
        cli("fair", pipe, "--fixed", "halfspace:0,0,1:8", "--fixed", "halfspace:0,0,-1:-22", "--order", 2, "-o", out)
    W, G, back = meshpde.read_mesh(out)
    assert np.array_equal(G, F) and np.abs(W - V).max() > 1e-3  # the same cells, moved
    for name, values in fields.cells.items():
        assert back.cells[name].dtype == values.dtype, name
        if name != "Normals":  # recomputed where vertices moved
            assert np.array_equal(back.cells[name], values), name
    assert back["GlobalNodeID"].dtype == np.int32 and np.array_equal(back["GlobalNodeID"], fields["GlobalNodeID"])


def test_vtk_interop_keeps_cells_types_and_the_frame(pipe):
    pytest.importorskip("vtk")
    V, F, fields = meshpde.read_mesh(pipe)
    fields.space = "RAS"
    W, G, back = meshpde.from_vtk(meshpde.to_vtk(V, F, fields))
    assert np.array_equal(G, F) and back.space == "RAS"
    assert back.cells["ModelFaceID"].dtype == np.int32
    assert np.array_equal(back.cells["ModelFaceID"], fields.cells["ModelFaceID"])
    assert back["GlobalNodeID"].dtype == np.int32


def test_a_correction_holds_the_labelled_caps(pipe):
    V, F, fields = meshpde.read_mesh(pipe)
    labels = fields.cells["ModelFaceID"]
    handle = int(np.argmin(np.linalg.norm(V - [2, 0, 0.3], axis=1)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        held = meshpde.correct(V, F, [handle], ["normal:3"], radius=12, units="cm", face_labels=labels)
        loose = meshpde.correct(V, F, [handle], ["normal:3"], radius=12, units="cm", face_labels=labels, caps="off")
    cap = np.unique(F[labels == 3])  # the cap at z = 0
    assert np.abs(held.displacement[cap]).max() == 0
    assert np.abs(loose.displacement[cap]).max() > 0.01
    caps = held.to_dict()["caps"]  # as `meshpde correct --json` reports them
    assert (caps["rule"], caps["held_vertices"], caps["label_array"]) == ("labels", 507, None)
    assert 3 in [c["label"] for c in caps["caps"]]
    assert sum(c["vertices"] for c in caps["caps"]) == 507  # the two ends' caps, apart
    # By shape, without the labels.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        auto = meshpde.correct(V, F, [handle], ["normal:3"], radius=12, units="cm", caps="auto")
    assert np.abs(auto.displacement[cap]).max() == 0


def test_the_batch_keeps_face_labels_and_holds_caps(pipe, tmp_path):
    row = meshpde.batch.process("correct", pipe, tmp_path,
                                {"vertices": [202], "moves": ["normal:3"], "radius": 12.0, "units": "cm"})
    assert row["status"] == "ok", row.get("error")
    V, F, fields = meshpde.read_mesh(row["output"])
    W, G, given = meshpde.read_mesh(pipe)
    assert np.array_equal(fields.cells["ModelFaceID"], given.cells["ModelFaceID"])
    assert fields.cells["ModelFaceID"].dtype == np.int32 and fields["GlobalNodeID"].dtype == np.int32
    assert "displacement" in fields
    cap = np.unique(F[given.cells["ModelFaceID"] != 2])
    assert np.abs(fields["displacement"][cap]).max() == 0
    # The cell normals follow the moved wall.
    moved = np.linalg.norm(fields["displacement"], axis=1) > 0
    touched = moved[F].any(axis=1)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    agree = np.abs((n * fields.cells["Normals"]).sum(axis=1))
    assert agree[touched].min() > 0.999


def test_a_model_in_centimetres_is_warned_about(tmp_path, cli):
    V, F = meshpde.generate.tube(radius=1.2, length=30, rings=600, segments=150)
    report = meshpde.check_units(V, F)
    assert report["implausible"] and report["suggested"] == "cm" and report["median_radius_mm"] == pytest.approx(1.2)
    assert "finer than any scanner resolves" in report["warning"]
    with pytest.warns(UserWarning, match="units=cm"):
        meshpde.info(V, F)
    path = tmp_path / "aorta-cm.vtp"
    meshpde.write_mesh(path, V, F)
    info = cli("info", path, "--json", json_out=True)
    assert "--units cm" in info["units_warning"]
    (tmp_path / "out").mkdir()
    row = meshpde.batch.process("curvature", path, tmp_path / "out")
    assert row["status"] == "ok" and "units=cm" in row["note"]
    assert meshpde.check_units(V, F, "cm")["warning"] is None
