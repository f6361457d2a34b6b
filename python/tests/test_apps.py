"""heat, wave, fair, interpolate and correct against the command-line tool on the same
input (equal to 1e-12 relative), and against the mathematics."""
import json

import warnings

import numpy as np
import pytest

import meshpde
from conftest import rel_diff


@pytest.fixture(scope="module")
def ico(tmp_path_factory):
    V, F = meshpde.generate.icosphere(3)
    path = tmp_path_factory.mktemp("ico") / "ico.ply"
    meshpde.write_mesh(path, V, F)
    return path, V, F


def test_heat_equals_the_cli(cli, ico, tmp_path):
    path, V, F = ico
    out = tmp_path / "h.ply"
    report = cli("heat", path, "--source", "0:1", "--flux", "7:0.5", "--dt", 0.01, "--steps", 20, "-o", out, "--json",
                 json_out=True)
    r = meshpde.heat(V, F, sources={0: 1.0}, flux={7: 0.5}, dt=0.01, steps=20)
    assert rel_diff(r.values, meshpde.read_mesh(out)[2]["u"]) <= 1e-12
    assert r.cg_iterations == report["cg_iterations"]


@pytest.mark.parametrize("laplacian", ["cotan", "intrinsic"])
def test_heat_with_either_laplacian_equals_the_cli(cli, ico, tmp_path, laplacian):
    path, V, F = ico
    out = tmp_path / "h.ply"
    report = cli("heat", path, "--source", "0:1", "--dt", 0.01, "--steps", 10, "--laplacian", laplacian, "-o", out,
                 "--json", json_out=True)
    r = meshpde.heat(V, F, sources={0: 1.0}, dt=0.01, steps=10, laplacian=laplacian)
    assert report["laplacian"] == laplacian
    assert rel_diff(r.values, meshpde.read_mesh(out)[2]["u"]) <= 1e-12
    with pytest.raises(meshpde.InputError, match="laplacian|cotan"):
        meshpde.heat(V, F, sources={0: 1.0}, steps=1, laplacian="spectral")


def test_heat_decays_a_spherical_harmonic(ico):
    # P2(z) on the unit sphere is an eigenfunction of lap with eigenvalue -6.
    _, V, F = ico
    V = V / np.linalg.norm(V, axis=1, keepdims=True)
    u0 = 1.5 * V[:, 2] ** 2 - 0.5
    t = 0.05
    r = meshpde.heat(V, F, initial=u0, dt=t / 200, steps=200)
    ratio = (r.values @ u0) / (u0 @ u0)
    assert ratio == pytest.approx(np.exp(-6 * t), rel=0.03)


def test_wave_with_impulse_equals_the_cli(cli, ico, tmp_path):
    path, V, F = ico
    out = tmp_path / "w.ply"
    report = cli("wave", path, "--impulse", "3:1", "--speed", 2, "--damping", 0.1, "--steps", 30, "-o", out, "--json",
                 json_out=True)
    energies = []
    r = meshpde.wave(V, F, impulses={3: 1.0}, speed=2.0, damping=0.1, steps=30,
                     callback=lambda k, u, ut: energies.append(meshpde.wave_energy(V, F, u, ut, speed=2.0)))
    assert rel_diff(r.values, meshpde.read_mesh(out)[2]["u"]) <= 1e-12
    assert rel_diff(energies, report["energy"]) <= 1e-12


def test_interpolate_scalar_equals_the_cli_and_is_exact_at_constraints(cli, ico, tmp_path):
    path, V, F = ico
    (tmp_path / "c.csv").write_text("vertex,value\n0,1\n10,-2\n100,0.5\n")
    out = tmp_path / "i.ply"
    cli("interpolate", path, "--constraints", tmp_path / "c.csv", "-o", out)
    u = meshpde.interpolate(V, F, [0, 10, 100], [1.0, -2.0, 0.5])
    assert rel_diff(u, meshpde.read_mesh(out)[2]["u"]) <= 1e-12
    assert np.allclose(u[[0, 10, 100]], [1, -2, 0.5], rtol=0, atol=1e-12)


def test_iterative_solves_stop_at_the_tolerance_asked(sphere):
    V, F = sphere
    direct = meshpde.interpolate(V, F, [0, 40], [1.5, -1.0], solver="direct")
    loose = meshpde.interpolate(V, F, [0, 40], [1.5, -1.0], solver="iterative", tolerance=1e-3)
    tight = meshpde.interpolate(V, F, [0, 40], [1.5, -1.0], solver="iterative", tolerance=1e-12)
    # the tight solve is the direct answer; the loose one measurably is not
    assert np.abs(tight - direct).max() <= 1e-8 * np.abs(direct).max()
    assert np.abs(loose - direct).max() > 1e2 * np.abs(tight - direct).max()
    fixed = np.flatnonzero(V[:, 2] < 0)
    f = meshpde.fair(V, F, fixed, solver="iterative", tolerance=1e-4)
    assert 0 < f.worst_residual <= 1e-4 and f.cg_iterations > 0
    # correct's iterative solve (the clamp, a vertex handle) likewise
    c = meshpde.correct(V, F, [0], [(0, 0, 0.1)], radius=0.6, boundary="clamp", solver="iterative", tolerance=1e-5)
    assert 0 < c.relative_residual <= 1e-5
    for bad in (0.0, -1e-8, 1.0, float("nan")):
        with pytest.raises(meshpde.InputError, match="tolerance"):
            meshpde.correct(V, F, [0], [(0, 0, 0.1)], radius=0.6, boundary="clamp", solver="iterative", tolerance=bad)
        with pytest.raises(meshpde.InputError, match="tolerance"):
            meshpde.interpolate(V, F, [0, 40], [1.5, -1.0], solver="iterative", tolerance=bad)
        with pytest.raises(meshpde.InputError, match="tolerance"):
            meshpde.fair(V, F, fixed, tolerance=bad)


def test_interpolate_reproduces_linear_fields():
    V, F = meshpde.generate.plane(nx=8, ny=8)
    f = lambda P: 1 + 2 * P[:, 0] - P[:, 1]  # noqa: E731
    # two rings held: the bi-Laplacian's natural boundary does not reproduce linear fields
    held = np.flatnonzero((V[:, 0] < 0.2) | (V[:, 0] > 0.8) | (V[:, 1] < 0.2) | (V[:, 1] > 0.8))
    u = meshpde.interpolate(V, F, held, f(V[held]))
    assert np.abs(u - f(V)).max() < 1e-9


@pytest.mark.parametrize("kind", ["scalar", "displacement"])
def test_interpolation_solver_equals_interpolate_after_every_edit(ico, kind):
    _, V, F = ico
    rng = np.random.default_rng(3)
    s = meshpde.InterpolationSolver(V, F, kind=kind, g1=0.1, g2=1.0)
    shape = () if kind == "scalar" else (3,)
    for step in range(30):
        action = rng.integers(3) if s.num_constraints > 1 else 0
        if action == 0:
            s.set_value(int(rng.integers(len(V))), rng.normal(size=shape))
        elif action == 1:
            s.remove(int(rng.choice(s.vertices)))
        else:
            s.set_value(int(rng.choice(s.vertices)), rng.normal(size=shape))
        u = s.solve()
        fresh = meshpde.interpolate(V, F, s.vertices, u[s.vertices], kind=kind, g1=0.1, g2=1.0, solver="direct")
        assert u.shape == fresh.shape
        assert rel_diff(u, fresh) <= 1e-10, f"step {step}"
    assert s.factorizations == 1  # every edit an update of the first factor
    assert not s.laplacian_factor  # a membrane part: the whole operator's factor
    with pytest.raises(meshpde.InputError, match="not constrained"):
        s.remove(next(v for v in range(len(V)) if v not in s.vertices))
    with pytest.raises(ValueError, match="kind"):
        meshpde.InterpolationSolver(V, F, kind="vector")


def test_interpolation_solver_fresh_starts_reuse_the_last_order():
    V, F = meshpde.generate.icosphere(4)  # 2,562 vertices: a CHOLMOD factor
    rng = np.random.default_rng(4)
    s = meshpde.InterpolationSolver(V, F)
    s.max_changes = 2
    for v in range(0, len(V), 300):
        s.set_value(v, rng.normal())
    s.solve()
    for step in range(9):
        s.set_value(int(rng.integers(len(V))), rng.normal())
        u = s.solve()
        fresh = meshpde.interpolate(V, F, s.vertices, u[s.vertices], solver="direct")
        assert rel_diff(u, fresh) <= 1e-10, f"step {step}"
    assert s.factorizations >= 3
    assert s.reused_orders == s.factorizations - 1
    assert s.laplacian_factor  # a plate with 9-12 constraints: the Laplacian's factor


def test_interpolation_solver_both_factors_give_the_same_field():
    V, F = meshpde.generate.icosphere(4)
    rng = np.random.default_rng(6)
    laplacian, bilaplacian = meshpde.InterpolationSolver(V, F), meshpde.InterpolationSolver(V, F)
    bilaplacian.laplacian_factor_up_to = 0  # always the bi-Laplacian's own factor
    for v in rng.choice(len(V), 6, replace=False):
        x = rng.normal()
        laplacian.set_value(int(v), x)
        bilaplacian.set_value(int(v), x)
    assert rel_diff(laplacian.solve(), bilaplacian.solve()) <= 1e-10
    assert laplacian.laplacian_factor and not bilaplacian.laplacian_factor


def test_interpolate_displacement_equals_the_cli(cli, ico, tmp_path):
    path, V, F = ico
    cons = {"constraints": [{"vertex": 0, "value": [0, 0, 0.1]}, {"vertex": 50, "value": [0.2, 0, 0]},
                            {"vertex": 200, "value": [0, 0, 0]}]}
    (tmp_path / "c.json").write_text(json.dumps(cons))
    out = tmp_path / "d.ply"
    cli("interpolate", path, "--constraints", tmp_path / "c.json", "--kind", "displacement", "-o", out)
    d = meshpde.interpolate(V, F, [0, 50, 200], [[0, 0, 0.1], [0.2, 0, 0], [0, 0, 0]])
    assert d.shape == (len(V), 3)
    assert rel_diff(d, meshpde.read_mesh(out)[2]["d"]) <= 1e-12


def test_fair_equals_the_cli(cli, tmp_path):
    V, F = meshpde.generate.plane(nx=10, ny=10)
    V = V.copy()
    V[:, 2] = np.sin(3 * V[:, 0]) * V[:, 1]
    path = tmp_path / "p.ply"
    meshpde.write_mesh(path, V, F)
    out = tmp_path / "f.ply"
    cli("fair", path, "--fixed", "boundary", "--order", 2, "-o", out)
    r = meshpde.fair(V, F, "boundary", order=2)
    assert rel_diff(r.V, meshpde.read_mesh(out)[0]) <= 1e-12
    boundary = np.flatnonzero((V[:, 0] < 1e-9) | (V[:, 0] > 1 - 1e-9) | (V[:, 1] < 1e-9) | (V[:, 1] > 1 - 1e-9))
    assert np.array_equal(r.V[boundary], V[boundary])
    assert r.after["min_angle_deg"] > 0


CORRECT_KEYS = ["moved_vertices", "max_displacement", "region_vertices", "new_self_intersections", "method", "boundary",
                "dynamic", "laplacian", "laplacian_reason", "relative_residual", "applied_fraction", "substeps",
                "intersection_action", "handles", "units"]


@pytest.mark.parametrize("extra", [[], ["--method", "springs", "--rings", 3], ["--dynamic", "--steps", 20],
                                   ["--boundary", "fade"]])
def test_correct_equals_the_cli(cli, data, tmp_path, extra):
    path = data("aorta-closed-6k.vtp")
    out = tmp_path / "c.vtp"
    region = ["--radius", 8] if "--rings" not in extra else []
    report = cli("correct", path, "--vertex", 500, "--move", "normal:2", *region, *extra, "-o", out, "--json",
                 json_out=True)
    V, F, _ = meshpde.read_mesh(path)
    kwargs = dict(radius=8.0) if not region == [] else {}
    if "--method" in extra:
        kwargs.update(method="springs", rings=3)
    if "--dynamic" in extra:
        kwargs.update(dynamic=True, steps=20)
    if "--boundary" in extra:
        kwargs.update(boundary="fade")
    r = meshpde.correct(V, F, [500], ["normal:2"], **kwargs)
    for key in CORRECT_KEYS:
        ours, theirs = getattr(r, key), report[key]
        if isinstance(theirs, float):
            assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-14), key
        else:
            assert ours == theirs, key
    assert set(report) == set(r.to_dict())  # one report, made by the library for both
    V_cli, _, fields = meshpde.read_mesh(out)
    # The input's points are Float32 and the output keeps their type: the positions are
    # the library's rounded to float; the displacement field (Float64) is exact.
    assert rel_diff(r.V, V_cli) <= 2 ** -23
    assert rel_diff(r.V.astype(np.float32).astype(np.float64), V_cli) <= 1e-12
    assert rel_diff(r.displacement, fields["displacement"]) <= 1e-12
    # the input is not modified
    assert np.array_equal(V, meshpde.read_mesh(path)[0])


def test_correct_moves_the_handle_and_holds_the_outside():
    V, F = meshpde.generate.icosphere(4, radius=10)
    r = meshpde.correct(V, F, [0, 5], [(0, 0, 1), "normal:-0.5"], radius=3.0)
    assert np.allclose(r.V[0] - V[0], [0, 0, 1], atol=1e-12)
    n5 = V[5] / np.linalg.norm(V[5])
    assert np.allclose(r.V[5] - V[5], -0.5 * n5, atol=1e-3)
    outside = np.setdiff1d(np.arange(len(V)), r.region)
    assert np.array_equal(r.V[outside], V[outside])
    assert r.handles == 2 and r.new_self_intersections == 0


def test_correct_with_the_fade_boundary_reaches_beyond_the_radius():
    V, F = meshpde.generate.tube(radius=5.0, length=60.0, rings=50, segments=32)
    v = int(np.argmin(np.linalg.norm(V - [5.0, 0.0, 30.0], axis=1)))
    clamp = meshpde.correct(V, F, [v], [(-2.0, 0, 0)], radius=6.0, boundary="clamp")
    fade = meshpde.correct(V, F, [v], [(-2.0, 0, 0)], radius=6.0, boundary="fade")
    assert clamp.boundary == "clamp" and fade.boundary == "fade"
    assert np.allclose(fade.V[v] - V[v], [-2.0, 0, 0], atol=1e-12)
    rho = np.linalg.norm(V - V[v], axis=1)
    moved = np.linalg.norm(fade.displacement, axis=1)
    assert moved[rho > 12.0].max() == 0.0              # nothing beyond twice the radius
    assert 0 < moved[(rho > 6.5) & (rho < 9.0)].max() < 0.2  # a little between R and 2R
    assert np.linalg.norm(clamp.displacement, axis=1)[rho > 6.5].max() == 0.0
    with pytest.raises(meshpde.InputError, match="fade"):
        meshpde.correct(V, F, [v], [(-2.0, 0, 0)], rings=4, boundary="fade")


@pytest.mark.parametrize("units,scale", [("cm", 10.0), ("m", 1000.0)])
def test_correct_in_other_units_is_the_millimetre_correction(units, scale):
    # A tube 60 mm long written in cm or m, the request in mm: the result is the mm
    # one in the mesh's unit, in a session too; read as mm the mesh is warned about.
    V, F = meshpde.generate.tube(radius=5, length=60, rings=40, segments=32)
    ref = meshpde.correct(V, F, [600], [(1, 0, 0.5)], radius=8.0)
    r = meshpde.correct(V / scale, F, [600], [(1, 0, 0.5)], radius=8.0, units=units)
    assert r.units == units and r.to_dict()["units"] == units
    assert np.abs(r.displacement * scale - ref.displacement).max() < 1e-9
    assert np.array_equal(r.V, V / scale + r.displacement)
    assert r.max_displacement == pytest.approx(ref.max_displacement)  # mm
    s = meshpde.CorrectionSession(V / scale, F)
    a = s.apply([600], [(1, 0, 0.5)], radius=8.0, units=units)
    assert np.abs(a.displacement * scale - ref.displacement).max() < 1e-9
    with pytest.warns(UserWarning, match=f"units={units}"):
        meshpde.correct(V / scale, F, [600], [(0.01, 0, 0)], radius=0.5)
    with pytest.raises(meshpde.InputError, match="inch"):
        meshpde.correct(V, F, [600], [(1, 0, 0)], radius=8.0, units="inch")
    c = meshpde.check_units(V / scale, F)
    assert c["implausible"] and c["suggested"] == units
    assert c["diagonal_mm"] == pytest.approx(meshpde.check_units(V, F)["diagonal_mm"] / scale)
    assert meshpde.check_units(V / scale, F, units) == dict(meshpde.check_units(V / scale, F, units),
                                                            implausible=False, suggested=None)


def test_correct_takes_per_vertex_tissue_arrays():
    # A constant array is the scalar, bit for bit; a heavy patch changes the dynamics.
    V, F = meshpde.generate.tube(radius=5, length=60, rings=40, segments=32)
    n = len(V)
    args = dict(radius=8.0, dynamic=True, steps=10)
    scalar = meshpde.correct(V, F, [600], [(1, 0, 0.5)], mass=0.3, elasticity=0.5, viscosity=0.8, **args)
    fields = meshpde.correct(V, F, [600], [(1, 0, 0.5)], mass=np.full(n, 0.3), elasticity=np.full(n, 0.5),
                             viscosity=np.full(n, 0.8), **args)
    assert np.array_equal(scalar.displacement, fields.displacement)
    heavy = np.full(n, 0.3)
    heavy[np.abs(V[:, 2] - 33) < 2] = 1.0
    patched = meshpde.correct(V, F, [600], [(1, 0, 0.5)], mass=heavy, elasticity=0.5, viscosity=0.8, **args)
    assert np.abs(patched.displacement - scalar.displacement).max() > 1e-4
    with pytest.raises(meshpde.InputError, match="outside"):
        meshpde.correct(V, F, [600], [(1, 0, 0.5)], viscosity=np.full(n, 1.5), **args)
    with pytest.raises(ValueError):
        meshpde.correct(V, F, [600], [(1, 0, 0.5)], mass=np.full(n - 1, 0.3), **args)


def test_a_radius_below_one_edge_warns_that_only_the_handle_moves():
    V, F = meshpde.generate.icosphere(2, radius=10)  # edges of about 4.4
    with pytest.warns(UserWarning, match="only the handles move"):
        r = meshpde.correct(V, F, [6], [(0, 0, 2)], radius=1.0)
    assert r.moved_vertices == 1 and "only the handles move" in r.region_warning
    assert r.to_dict()["region_warning"] == r.region_warning
    assert meshpde.correct(V, F, [6], [(0, 0, 2)], radius=12.0).region_warning is None


def test_correction_session_undo_and_redo():
    V, F = meshpde.generate.icosphere(3, radius=10)
    s = meshpde.CorrectionSession(V, F)
    assert not s.can_undo
    a = s.apply([0], [(0, 0, 1)], radius=4.0)
    b = s.apply([0], [(0, 0, 1)], radius=4.0)
    assert np.allclose(s.V[0] - V[0], [0, 0, 2])
    s.undo()
    assert np.array_equal(s.V, a.V) and s.can_redo
    s.redo()
    assert np.array_equal(s.V, b.V)
    s.undo()
    s.undo()
    assert np.array_equal(s.V, V) and np.array_equal(s.original, V)
    with pytest.raises(meshpde.InputError):
        s.undo()
    assert s.new_self_intersections() == 0


def test_correct_with_image_guidance_reports_the_image(data):
    if not meshpde.has_medical:
        pytest.skip("built without meshpde::medical")
    V, F, _ = meshpde.read_mesh(data("aorta-closed-6k.vtp"))
    r = meshpde.correct(V, F, [500], ["normal:1"], radius=9.0, image=str(data("aorta-mra.mha")), space="ras")
    assert r.image["space"] == "RAS" and r.image["pulled_vertices"] > 0
    values, affine = meshpde.read_volume(data("aorta-mra.mha"))
    r2 = meshpde.correct(V, F, [500], ["normal:1"], radius=9.0, image=(values, affine), space="ras")
    assert np.abs(r2.V - r.V).max() <= 1e-9
    # the aorta is in RAS: read as LPS its region lies outside the image, refused in words
    with pytest.raises(meshpde.InputError, match="none of the region.s .* vertices lies inside the image.*is the mesh in RAS"):
        meshpde.correct(V, F, [500], ["normal:1"], radius=9.0, image=(values, affine), space="lps")
    # An image cut through the handle (the edge of a field of view across the region):
    # the vertices beyond it are counted and follow the drag unguided, the rest are pulled.
    lps = V[500] * [-1, -1, 1]  # the mesh is RAS
    ijk = np.linalg.solve(affine[:3, :3], lps - affine[:3, 3])
    region = r.region
    span = np.ptp([np.linalg.solve(affine[:3, :3], V[v] * [-1, -1, 1] - affine[:3, 3]) for v in region], axis=0)
    axis = int(np.argmax(span))
    cut = np.take(values, np.arange(int(np.floor(ijk[axis])) + 1), axis=axis)
    half = meshpde.correct(V, F, [500], ["normal:1"], radius=9.0, image=(cut, affine), space="ras")
    assert half.image["outside_vertices"] > 10 and half.image["pulled_vertices"] > 10
    assert half.image["outside_vertices"] + half.image["pulled_vertices"] == r.image["pulled_vertices"]


@pytest.mark.parametrize("solver", ["global", "iterative"])
def test_correct_solvers_agree_with_the_direct_one_and_the_cli(cli, ico, tmp_path, solver):
    path, V, F = ico
    out = tmp_path / "c.ply"
    # The global and iterative solvers take the clamp boundary (held vertex handles).
    report = cli("correct", path, "--vertex", 0, "--move", "0,0,0.1", "--radius", 0.6, "--solver", solver,
                 "--boundary", "clamp", "--tolerance", 1e-12, "-o", out, "--json", json_out=True)
    assert report["solver"] == solver
    direct = meshpde.correct(V, F, [0], [(0, 0, 0.1)], radius=0.6, boundary="clamp")
    other = meshpde.correct(V, F, [0], [(0, 0, 0.1)], radius=0.6, solver=solver, boundary="clamp")
    assert np.abs(other.V - direct.V).max() <= 1e-7 * 0.1
    assert np.array_equal(other.region, direct.region)
    assert np.abs(meshpde.read_mesh(out)[0] - direct.V).max() <= 1e-7 * 0.1
    with pytest.raises(meshpde.InputError, match="static fem"):
        meshpde.correct(V, F, [0], [(0, 0, 0.1)], radius=0.6, solver=solver, dynamic=True)


def test_the_default_solver_is_auto_and_says_which_one_ran(cli, ico, tmp_path):
    # Auto tries the multigrid only on meshes of 50,000 free vertices or more; below,
    # the direct solver, and every report names the one that ran.
    path, V, F = ico
    report = cli("correct", path, "--vertex", 0, "--move", "0,0,0.1", "--radius", 0.6, "-o", tmp_path / "c.ply",
                 "--json", json_out=True)
    assert report["solver"] == "direct" and report["condition_estimate"] > 0
    assert meshpde.correct(V, F, [0], [(0, 0, 0.1)], radius=0.6).solver == "direct"
    assert meshpde.correct(V, F, [0], [(0, 0, 0.1)], radius=0.6, solver="global", boundary="clamp").solver == "global"
    fixed = np.flatnonzero(V[:, 2] <= -0.5)
    assert meshpde.fair(V, F, fixed).solver == "direct"
    assert meshpde.fair(V, F, fixed, solver="global").solver == "global"
    assert meshpde.fair(V, F, fixed, regularize=True, order=1, steps=2).solver == "iterative"
    report = cli("fair", path, "--fixed", "halfspace:0,0,1:-0.5", "-o", tmp_path / "f.ply", "--json",
                 json_out=True)
    assert report["solver"] == "direct"
    with pytest.raises(ValueError, match="'auto', 'direct', 'global' or 'iterative'"):
        meshpde.interpolate(V, F, [0], [1.0], solver="cholesky")


@pytest.mark.parametrize("laplacian", ["cotan", "intrinsic"])
def test_poke_with_either_laplacian_equals_the_python_session(cli, ico, tmp_path, laplacian):
    # On the icosphere (Delaunay already) both operators are the same: the same forces.
    # Steps back to back wait for each factor, so the two runs see the same domains.
    path, V, F = ico
    probe = tmp_path / "probe.csv"
    probe.write_text("0,0,0,0\n0.05,-0.02,0.01,-0.03\n0.08,-0.02,0.01,-0.03\n")
    report = cli("poke", path, "--vertex", 5, "--path", probe, "--settle", 0, "--no-realtime", "--laplacian", laplacian,
                 "--json", json_out=True)
    assert report["laplacian"] == laplacian and report["solver"] == "factored"
    h = meshpde.HapticSession(V, F, wait_for_factors=True, laplacian=laplacian)
    h.touch(5)
    forces = []
    for k in range(1, len(report["samples"]) + 1):
        t = k * 1e-3
        h.move_probe(np.array([-0.02, 0.01, -0.03]) * min(1.0, t / 0.05))
        forces.append(h.step(1e-3))
    cli_forces = np.array([s["force"] for s in report["samples"]])
    assert rel_diff(np.array(forces), cli_forces) <= 1e-9
    with pytest.raises(meshpde.InputError, match="laplacian|cotan"):
        meshpde.HapticSession(V, F, laplacian="spectral")


def test_the_resolution_study_runs_and_the_fade_agrees_better(tmp_path):
    # bench/python/resolution_study.py --quick (the tube only), as docs/vessel-correction.md runs it.
    import json
    import subprocess
    import sys
    from pathlib import Path
    script = Path(__file__).resolve().parents[2] / "bench" / "python" / "resolution_study.py"
    out = tmp_path / "study.json"
    subprocess.run([sys.executable, str(script), "--quick", "--json", str(out), "--out", str(tmp_path / "r.png")],
                   check=True, capture_output=True, timeout=600)
    rows = json.loads(out.read_text())
    by = {(r["method"], r["R_over_h"]): r for r in rows}
    assert set(by) == {(m, R) for m in ("fem clamp", "fem fade", "springs") for R in (5, 10, 20)}
    for R in (5, 10, 20):
        assert by[("fem fade", R)]["s01"] < by[("fem clamp", R)]["s01"]
        assert by[("fem fade", R)]["order"] > 1.0  # it converges
    assert (tmp_path / "r.png").stat().st_size > 10000


def test_correct_at_surface_points_with_the_smooth_boundary():
    # A handle at a surface point moves that point by the move; the default boundary is
    # smooth, with a handle of a quarter of the radius; nothing at or beyond the radius on
    # the surface moves.
    V, F = meshpde.generate.tube(radius=5.0, length=60.0, rings=50, segments=32)
    x = np.array([[5.0, 0.4, 30.3]])
    r = meshpde.correct(V, F, points=x, moves=[(1.0, 0.0, 0.5)], radius=8.0)
    assert r.boundary == "smooth" and r.to_dict()["handle_radius"] == pytest.approx(2.0)
    h = r.to_dict()["handle_points"][0]
    tri, w = F[h["triangle"]], np.array(h["barycentric"])
    # A handle with a size is read by the quadratic around it: exactly the move there, its
    # triangle's corners to the mesh's interpolation error (reported)
    assert h["reading"] == "quadratic"
    assert np.linalg.norm(w @ r.displacement[tri] - [1.0, 0.0, 0.5]) < 0.05 * np.hypot(1.0, 0.5)
    assert np.allclose(w @ r.displacement[tri], h["corners_displacement"], atol=1e-12)
    exact = meshpde.correct(V, F, points=x, moves=[(1.0, 0.0, 0.5)], radius=8.0, handle_radius=0.0)
    assert exact.to_dict()["handle_points"][0]["reading"] == "corners"
    assert np.allclose(w @ exact.displacement[tri], [1.0, 0.0, 0.5], atol=1e-9)
    s = meshpde.geodesic_distance(V, F, x)
    moved = np.linalg.norm(r.displacement, axis=1)
    assert moved[s >= 8.0].max() == 0.0 and moved[s < 2.0].min() > 0.3
    # the CLI's @X,Y,Z vertex spelling, and vertices with points together
    both = meshpde.correct(V, F, ["@5,0,10"], [(0.5, 0, 0), "normal:-1"], points=x, radius=6.0)
    assert both.handles == 2
    with pytest.raises(ValueError, match="one move per handle"):
        meshpde.correct(V, F, points=x, moves=[(1, 0, 0), (1, 0, 0)], radius=8.0)
    session = meshpde.CorrectionSession(V, F)
    assert session.apply(points=x, moves=["normal:1"], radius=8.0, handle_radius=0.0).moved_vertices > 3
    # a point given 100 mm beyond the tube's end is warned about (and still moves the
    # nearest wall point); the report gives it as given, with its distance
    assert r.handle_warning is None and h["distance_to_surface"] < 0.1
    with pytest.warns(UserWarning, match="lies 100 mm from the surface, farther than the region's 8 mm"):
        far = meshpde.correct(V, F, points=[[5.0, 0.0, 160.0]], moves=[(1.0, 0.0, 0.5)], radius=8.0)
    assert "frame and unit" in far.handle_warning and far.moved_vertices > 3
    assert far.to_dict()["handle_points"][0]["given"] == [5.0, 0.0, 160.0]
    assert far.to_dict()["handle_points"][0]["distance_to_surface"] == pytest.approx(100.0, abs=0.1)
    with pytest.warns(UserWarning, match="lies 100 mm from the nearest vertex"):
        meshpde.correct(V, F, ["@5,0,160"], [(1.0, 0.0, 0.5)], radius=8.0)


def test_geodesic_distance_is_the_unrolled_straight_line_on_a_cylinder():
    V, F = meshpde.generate.tube(radius=1.0, length=6.0, rings=97, segments=100)
    src = int(np.argmin(np.linalg.norm(V - [1.0, 0.0, 3.0], axis=1)))
    d = meshpde.geodesic_distance(V, F, src, radius=2.0)
    theta = np.arctan2(V[:, 1], V[:, 0]) - np.arctan2(V[src, 1], V[src, 0])
    theta = np.remainder(theta + np.pi, 2 * np.pi) - np.pi
    exact = np.hypot(theta, V[:, 2] - V[src, 2])
    inside = exact < 1.9
    assert np.all(np.isfinite(d[inside])) and np.abs(d[inside] - exact[inside]).max() < 0.01
    assert np.all(np.isinf(d[exact > 2.1]))
    with pytest.raises(IndexError):
        meshpde.geodesic_distance(V, F, [len(V)])


def test_quadratic_reading_reads_a_smooth_field_far_closer_than_the_corners():
    # z on a sphere of radius 10, read at scattered points: W @ z against the value on the
    # sphere straight out from each point, and against the corners' interpolation.
    V, F = meshpde.generate.icosphere(4)
    V = 10 * np.asarray(V)
    rng = np.random.default_rng(3)
    P = rng.normal(size=(20, 3))
    P = 10 * P / np.linalg.norm(P, axis=1)[:, None]
    W = meshpde.quadratic_reading(V, F, P)
    assert W.shape == (20, len(V)) and np.allclose(W.sum(axis=1), 1.0)
    faces, bary = meshpde.closest_surface_points(V, F, P)
    x = (bary[:, :, None] * V[F[faces]]).sum(1)
    exact = 10 * x[:, 2] / np.linalg.norm(x, axis=1)
    quadratic = np.abs(W @ V[:, 2] - exact).max()
    linear = np.abs(x[:, 2] - exact).max()
    assert quadratic < 0.05 * linear
    # a correction's handle with a size reads its displacement with these weights
    T, TF = meshpde.generate.tube(radius=5.0, length=60.0, rings=50, segments=32)
    r = meshpde.correct(T, TF, points=[[5.0, 0.4, 30.3]], moves=[(1.0, 0.0, 0.5)], radius=8.0)
    assert np.allclose(meshpde.quadratic_reading(T, TF, [[5.0, 0.4, 30.3]]) @ r.displacement, [[1.0, 0.0, 0.5]],
                       atol=1e-9)
    with pytest.raises(ValueError):
        meshpde.quadratic_reading(V, F, [[np.nan, 0.0, 0.0]])


def test_tissue_brushes_as_the_command_line_takes_them():
    # brushes=["[PROPERTY:]V:RADIUS:VALUE", ...]: the library parses them for both front ends.
    V, F = meshpde.generate.tube(radius=5.0, length=60.0, rings=50, segments=32)
    handle = int(np.argmin(np.linalg.norm(V - [5.0, 0.0, 30.0], axis=1)))
    plain = meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0)
    ones = meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0, brushes=["0:1000:1"])
    assert np.abs(ones.displacement - plain.displacement).max() <= 1e-12
    stiff = meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0, brushes=["@5,0,33:3:5"])
    assert np.abs(stiff.displacement - plain.displacement).max() > 1e-3
    # A tissue brush over the whole mesh is the scalar option.
    scalar = meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0, dynamic=True, steps=10, mass=0.3)
    brushed = meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0, dynamic=True, steps=10,
                              brushes=["mass:0:1000:0.3"])
    assert np.abs(brushed.displacement - scalar.displacement).max() <= 1e-12
    with pytest.raises(meshpde.InputError, match="brush 'bogus:0:1:1'"):
        meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0, brushes=["bogus:0:1:1"])
    with pytest.raises(meshpde.InputError, match="a list of"):
        meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0, brushes="0:1:1")
    # A brush at a point far off the wall (40 mm: another frame or unit?) is warned about.
    with pytest.warns(UserWarning, match="'@5,40,33'.*nearest vertex"):
        meshpde.correct(V, F, [handle], [(1.0, 0.0, 0.0)], radius=10.0, brushes=["@5,40,33:3:5"])


def test_a_far_point_in_a_selection_is_warned_about_and_a_near_one_is_not():
    V, F = meshpde.generate.icosphere(3, radius=10)
    with pytest.warns(UserWarning, match="vertex '@0,40,0': the point lies 30 from its nearest vertex"):
        far = meshpde.fair(V, F, "rings:@0,40,0:2")
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        near = meshpde.fair(V, F, "rings:@0,10.1,0:2")
    assert np.array_equal(far.V, near.V)  # the same vertex either way: a warning, not a refusal
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # as an error, it is raised from the call
        with pytest.raises(UserWarning, match="nearest vertex"):
            meshpde.fair(V, F, "rings:@0,40,0:2")


@pytest.mark.parametrize("function", ["correct", "CorrectionSession.apply"])
def test_the_correction_defaults_shown_are_the_librarys(function):
    # The signatures show the defaults; the library (CorrectionParams) owns them.
    import inspect
    f = meshpde.correct if function == "correct" else meshpde.CorrectionSession.apply
    shown = {k: p.default for k, p in inspect.signature(f).parameters.items() if p.default is not inspect.Parameter.empty}
    library = meshpde._meshpde._correction_defaults()
    assert set(library) <= set(shown), set(library) - set(shown)
    differ = {k: (shown[k], v) for k, v in library.items() if shown[k] != v}
    assert not differ, differ
