"""Reading, writing, generators and diagnostics, against the command-line tool."""
import numpy as np
import pytest

import meshpde
from conftest import rel_diff


@pytest.mark.parametrize("kind,args,kwargs", [
    ("icosphere", ["--level", 2, "--radius", 3], dict(level=2, radius=3)),
    ("latlong", ["--n", 5], dict(n=5)),
    ("geodesic", ["--base", "tetrahedron", "--frequency", 3], dict(base="tetrahedron", frequency=3)),
    ("tube", ["--rings", 6, "--segments", 8], dict(rings=6, segments=8)),
    ("plane", ["--nx", 4, "--ny", 3], dict(nx=4, ny=3)),
    ("fins", ["--k", 3, "--n", 2], dict(k=3, n=2)),
    ("bifurcation", ["--cell", 1.0], dict(cell=1.0)),
])
def test_generators_equal_the_cli(cli, tmp_path, kind, args, kwargs):
    out = tmp_path / "g.ply"
    cli("generate", kind, *args, "-o", out)
    V0, F0, _ = meshpde.read_mesh(out)
    V, F = getattr(meshpde.generate, kind)(**kwargs)
    assert V.shape == V0.shape and np.array_equal(F, F0)
    assert np.abs(V - V0).max() == 0


def test_generator_names_are_the_cli_kinds():
    assert meshpde.generate.names() == ["latlong", "icosphere", "geodesic", "tube", "bifurcation", "plane", "fins"]


@pytest.mark.parametrize("ext", [".ply", ".obj", ".off", ".stl", ".vtp", ".vtk"])
def test_write_then_read_keeps_the_mesh(tmp_path, sphere, ext):
    if ext in (".vtp", ".vtk") and not meshpde.has_medical:
        pytest.skip("built without meshpde::medical")
    V, F = sphere
    path = tmp_path / f"s{ext}"
    fields = {"u": V[:, 0] * 2.0, "d": V * 0.5} if ext in (".ply", ".vtp", ".vtk") else None
    meshpde.write_mesh(path, V, F, fields)
    V2, F2, f2 = meshpde.read_mesh(path)
    if ext == ".stl":  # binary STL stores float32 corners; reading welds them in a new order
        assert len(V2) == len(V) and len(F2) == len(F)
        assert np.abs(V2[F2] - V[F]).max() <= 1e-6 * np.abs(V).max()
    else:
        assert np.array_equal(F2, F) and np.array_equal(V2, V)
    if fields:
        assert set(f2) == {"u", "d"}
        assert f2["u"].shape == (len(V),) and f2["d"].shape == (len(V), 3)
        assert np.array_equal(f2["u"], fields["u"]) and np.array_equal(f2["d"], fields["d"])


def test_writer_reports_fields_it_cannot_keep(tmp_path, sphere):
    V, F = sphere
    with pytest.warns(UserWarning):
        warnings = meshpde.write_mesh(tmp_path / "s.obj", V, F, {"u": V[:, 0]})
    assert warnings


def test_info_equals_the_cli(cli, data):
    path = data("bunny-3k.off")
    V, F, _ = meshpde.read_mesh(path)
    ours = meshpde.info(V, F)
    theirs = cli("info", path, "--json", json_out=True)
    for key, value in theirs.items():
        if isinstance(value, float):
            assert ours[key] == pytest.approx(value, rel=1e-12, abs=1e-300), key
        elif isinstance(value, list) and key.startswith("bbox"):
            assert np.allclose(ours[key], value, rtol=1e-12), key
        elif key == "units_warning":
            # The same sizes and unit, each front end naming its input and option its way.
            assert value and ours[key] and "give --units m" in value and "give units=m" in ours[key]
            assert value.split(": ", 1)[1].replace("--units ", "units=") == ours[key].split(": ", 1)[1]
        elif key in ours:
            assert ours[key] == value, key


def test_real_vtp_keeps_its_point_data(data):
    if not meshpde.has_medical:
        pytest.skip("built without meshpde::medical")
    V, F, fields = meshpde.read_mesh(data("aorta-closed-6k.vtp"))
    assert V.shape[1] == 3 and F.shape[1] == 3 and F.max() < len(V)
    for name, values in fields.items():
        assert values.shape[0] == len(V), name


def test_outward_normals_point_out_of_an_inward_oriented_sphere(sphere):
    V, F = sphere
    inward = F[:, ::-1]
    n = meshpde.vertex_normals(V, inward)
    assert np.all(np.einsum("ij,ij->i", n, V) > 0.9)
    n_raw = meshpde.vertex_normals(V, inward, outward=False)
    assert np.all(np.einsum("ij,ij->i", n_raw, V) < -0.9)


def test_self_intersections_finds_a_pushed_through_vertex(sphere):
    V, F = sphere
    assert meshpde.self_intersections(V, F).shape == (0, 2)
    W = V.copy()
    W[0] = -W[0] * 1.5  # through the sphere and out on the other side
    pairs = meshpde.self_intersections(W, F)
    assert len(pairs) > 0 and pairs.shape[1] == 2
    touched = set(np.flatnonzero((F == 0).any(axis=1)))
    assert all(i in touched or j in touched for i, j in pairs)


def test_hausdorff_distance_between_offset_and_nested_planes():
    V, F = meshpde.generate.plane(nx=8, ny=8, size=2.0)
    W = V.copy()
    W[:, 2] += 0.3
    assert meshpde.hausdorff_distance(V, F, W, F) == pytest.approx(0.3, abs=1e-12)
    # The same surface, finer: no distance either way.
    Vs, Fs = meshpde.generate.subdivide(V, F)
    assert meshpde.hausdorff_distance(V, F, Vs, Fs) == pytest.approx(0.0, abs=1e-12)
    # A quarter of the plane lies on the whole (directed 0), not the other way round.
    small = (V[:, 0] <= V[:, 0].mean() + 1e-9) & (V[:, 1] <= V[:, 1].mean() + 1e-9)
    keep = small[F].all(axis=1)
    idx = np.flatnonzero(small)
    remap = -np.ones(len(V), dtype=np.int64)
    remap[idx] = np.arange(len(idx))
    Vq, Fq = V[idx], remap[F[keep]]
    assert meshpde.hausdorff_distance(Vq, Fq, V, F, directed=True) == pytest.approx(0.0, abs=1e-12)
    assert meshpde.hausdorff_distance(V, F, Vq, Fq, directed=True) == pytest.approx(np.sqrt(2.0), rel=1e-9)
    assert meshpde.hausdorff_distance(V, F, Vq, Fq) == pytest.approx(np.sqrt(2.0), rel=1e-9)


def test_render_to_array_and_file(tmp_path, sphere):
    V, F = sphere
    img = meshpde.render(V, F, field=V[:, 2], width=64, height=48)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    assert img.std() > 0  # not a blank picture
    assert meshpde.render(V, F, path=tmp_path / "s.png", width=64, height=48) is None
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_read_volume_affine_maps_voxels_to_lps(data):
    if not meshpde.has_medical:
        pytest.skip("built without meshpde::medical")
    values, affine = meshpde.read_volume(data("aorta-levelset.mha"))
    assert values.ndim == 3 and values.dtype == np.float32
    assert affine.shape == (4, 4) and np.array_equal(affine[3], [0, 0, 0, 1])
    # The level set is zero on the registered RAS mesh: sample it trilinearly at the
    # vertices through the affine (LPS = RAS with x, y negated).
    V, F, _ = meshpde.read_mesh(data("aorta-closed-6k.vtp"))
    lps = V * [-1, -1, 1]
    ijk = np.linalg.solve(affine[:3, :3], (lps - affine[:3, 3]).T).T
    from scipy.ndimage import map_coordinates
    phi = map_coordinates(values, ijk.T, order=1)
    spacing = np.linalg.norm(affine[:3, :3], axis=0)
    assert np.abs(phi).mean() < 0.1 * spacing.min()


def test_info_of_a_volume_file_equals_the_cli(cli, data):
    if not meshpde.has_medical:
        pytest.skip("built without meshpde::medical")
    path = data("aorta-mra.mha")
    ours = meshpde.info(path)
    theirs = cli("info", path, "--json", json_out=True)
    assert ours["kind"] == "volume" and list(ours["dims"]) == theirs["dims"]
    assert ours["orientation"] == theirs["orientation"] and ours["frame"] == "LPS"
    for key in ["min", "max", "mean"]:
        assert ours[key] == pytest.approx(theirs[key], rel=1e-12)
    values, affine = meshpde.read_volume(path)
    assert ours["min"] == values.min() and ours["max"] == values.max()
    assert np.allclose(ours["origin"], affine[:3, 3])


def test_info_of_a_mesh_file_equals_info_of_its_arrays(data):
    path = data("bunny-3k.off")
    V, F, _ = meshpde.read_mesh(path)
    with pytest.warns(UserWarning, match="give units=m"):
        by_path = meshpde.info(path)
    with pytest.warns(UserWarning, match="give units=m"):
        by_arrays = meshpde.info(V, F)
    # The units warning names its input: the file, or V.
    assert by_path.pop("units_warning").startswith(str(path)) and by_arrays.pop("units_warning").startswith("V:")
    assert by_path == by_arrays


def test_geodesic_and_ring_balls(sphere):
    V, F = sphere
    ball = meshpde.geodesic_ball(V, F, 0, 0.5)
    assert ball[0] == 0
    # every vertex of the ball is within 0.5 straight-line distance too (edge paths are longer)
    assert np.all(np.linalg.norm(V[ball] - V[0], axis=1) < 0.5)
    ring1 = meshpde.ring_ball(V, F, 0, 1)
    neighbours = set(F[(F == 0).any(axis=1)].ravel())
    assert set(ring1) == neighbours
    with pytest.raises(IndexError):
        meshpde.ring_ball(V, F, len(V), 1)
    with pytest.raises(ValueError, match="radius"):
        meshpde.geodesic_ball(V, F, 0, -1.0)
