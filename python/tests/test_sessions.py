"""The stateful classes against independent scipy solves."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import meshpde


def unit_edge_icosphere(level):
    V, F = meshpde.generate.icosphere(level)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    E = np.unique(np.sort(E, axis=1), axis=0)
    return V / np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean(), F


def dirichlet_solve(A, held, values):
    """x with x[held] = values and (A x)[free] = 0."""
    n = A.shape[0]
    free = np.setdiff1d(np.arange(n), held)
    x = np.zeros((n,) + np.shape(values)[1:])
    x[held] = values
    A = sp.csr_matrix(A)
    x[free] = spla.spsolve(A[free][:, free].tocsc(), -(A[free][:, held] @ x[held]))
    return x


@pytest.mark.parametrize("solver", ["factored", "cg"])
def test_haptic_settled_force_matches_a_full_matrix_solve(solver):
    # The C++ test Haptics.SettledForceMatchesAnIndependentFullMatrixSolve, from Python.
    V, F = unit_edge_icosphere(4)
    h = meshpde.HapticSession(V, F, solver=solver, wait_for_factors=True)  # steps far faster than real time
    v, offset = 5, np.array([0.1, -0.25, 0.05])
    h.touch(v)
    h.move_probe(offset)
    for _ in range(300):
        f = h.step(5e-2)
    K, M = meshpde.stiffness(V, F), meshpde.mass(V, F)
    L = 3.0  # default influence: 3 mean edge lengths (here 1 each)
    Kt = M + L ** 4 * (K @ sp.diags(1 / M.diagonal()) @ K)
    u = dirichlet_solve(Kt, [v], offset[None, :])
    reaction = (Kt @ u)[v]
    assert np.linalg.norm(f + reaction) <= 0.01 * np.linalg.norm(reaction)
    assert h.active_vertices < len(V) / 2
    log = h.log()
    assert log["force"].shape == (300, 3) and np.allclose(log["force"][-1], f)
    if solver == "factored":  # waiting for each factor: all but the first few steps use one
        assert h.factorizations > 1 and log["factored"][-100:].all()
        assert 0 < log["new_factor"].sum() <= h.factorizations
    else:
        assert h.factorizations == 0 and not log["factored"].any() and not log["new_factor"].any()
    # Where each step's time went: the parts are timed inside the step, so they add up
    # to no more than its latency, and the solve is one of them.
    parts = sum(log[k] for k in ("install_us", "solve_us", "propose_us", "publish_us"))
    assert (parts <= log["latency_us"] + 1e-3).all() and (log["solve_us"] > 0).all()


def test_haptic_session_names_a_bad_solver():
    V, F = unit_edge_icosphere(2)
    with pytest.raises(ValueError, match="solver"):
        meshpde.HapticSession(V, F, solver="multigrid")


def test_pde_session_steady_reaction_is_the_assembled_row():
    V, F = meshpde.generate.icosphere(3)
    s = meshpde.PdeSession(V, F, components=1, g1=1.0, g2=0.1, g0=0.5, tolerance=1e-12)
    s.activate_all()
    s.constrain(0, 1.0)
    s.constrain(7, -0.5)
    r = s.solve_steady()
    assert r["converged"]
    K, M = meshpde.stiffness(V, F), meshpde.mass(V, F)
    Kt = 0.5 * M + K + 0.1 * (K @ sp.diags(1 / M.diagonal()) @ K)
    u = dirichlet_solve(Kt, [0, 7], [1.0, -0.5])
    assert np.abs(s.values[:, 0] - u).max() <= 1e-9
    assert np.allclose(s.reaction_forces[:, 0], (Kt @ u)[[0, 7]], rtol=1e-8, atol=1e-10)
    assert list(s.constrained_vertices) == [0, 7]


def test_pde_session_poke_grows_a_local_domain():
    V, F = unit_edge_icosphere(4)
    s = meshpde.PdeSession(V, F, components=3, alpha=1, b1=1, b2=0.01, g0=1, g2=100, self_adjusting=True)
    s.constrain(0, [0, 0, -0.5])
    sizes = [s.step(1e-3)["free_vertices"] for _ in range(20)]
    assert 0 < sizes[-1] < len(V) / 2
    assert np.linalg.norm(s.reaction_forces[0]) > 0
    assert np.allclose(s.values[0], [0, 0, -0.5])


def test_drag_session_equals_a_direct_solve_on_its_region():
    V, F = meshpde.generate.icosphere(4, radius=10)
    K, M = meshpde.stiffness(V, F), meshpde.mass(V, F)
    A = K @ sp.diags(1 / M.diagonal()) @ K
    R = 3.0
    # The clamp: the region held at zero outside, K M^-1 K inside.
    d = meshpde.DragSession(V, F, [0], radius=R, boundary="clamp")
    assert d.boundary == "clamp"
    P = d.positions([[0, 0, 1]])
    region = d.region
    assert 0 not in region and len(region) > 10
    held = np.setdiff1d(np.arange(len(V)), region)
    move = np.zeros((len(held), 3))
    move[held == 0] = [0, 0, 1]
    ref = dirichlet_solve(A, held, move)
    assert np.abs((P - V) - ref).max() <= 1e-9
    # linear in the handle's displacement: no new solve
    P2 = d.positions([[0, 0, 2]])
    assert np.abs((P2 - V) - 2 * (P - V)).max() <= 1e-12
    assert d.factorizations == 1
    # The smooth boundary (the default): the same region plus the documented foundation
    # 1e3 / R^4 x^2 / (1 - x)^4 M_i, x = (s / R - 0.5) / 0.5 capped to [0, 0.98], s the
    # surface distance from the handle, built here from geodesic_distance.
    s = meshpde.DragSession(V, F, [0], radius=R, handle_radius=0)
    assert s.boundary == "smooth" and s.handle_radius == 0
    assert np.array_equal(np.sort(s.region), np.sort(region))
    dist = meshpde.geodesic_distance(V, F, [0])
    x = np.clip((dist / R - 0.5) / 0.5, 0, 0.98)
    kappa = np.where(np.isin(np.arange(len(V)), region), 1e3 / R**4 * x**2 / (1 - x) ** 4 * M.diagonal(), 0)
    smooth_ref = dirichlet_solve(A + sp.diags(kappa), held, move)
    Ps = s.positions([[0, 0, 1]])
    assert np.abs((Ps - V) - smooth_ref).max() <= 1e-9
    assert np.abs((Ps - V) - ref).max() > 0.01  # the foundation changes the answer
    # Nothing beyond 0.95 R moves more than 0.2 % of the drag.
    assert np.linalg.norm(Ps - V, axis=1)[dist > 0.95 * R].max() <= 2e-3
    # It is correct()'s smooth rule with the same vertex handle of size 0.
    c = meshpde.correct(V, F, [0], ["0,0,1"], radius=R, handle_radius=0, laplacian="cotan",
                        allow_intersections=True)
    assert np.abs(c.V - Ps).max() <= 1e-9
    with pytest.raises(meshpde.InputError, match="clamp"):
        s.grow()
    with pytest.raises(meshpde.InputError, match="clamp"):
        meshpde.DragSession(V, F, [0], radius=R, margin=True)
    with pytest.raises(meshpde.InputError, match="smooth, clamp or fade"):
        meshpde.DragSession(V, F, [0], radius=R, boundary="soft")


def test_drag_session_takes_sized_and_point_handles_as_correct_does():
    V, F = meshpde.generate.icosphere(4, radius=10)
    R = 4.0
    # A point between vertices, near vertex 0, and vertex 0 itself.
    far = np.argsort(np.linalg.norm(V - V[0], axis=1))[8]
    point = 0.6 * V[0] + 0.4 * V[far]
    moves = np.array([[0, 0, 1.0], [0.3, -0.2, 0.5]])
    s = meshpde.DragSession(V, F, [0], radius=R, points=[point])
    assert s.handle_radius == pytest.approx(R / 4)  # correct()'s default size
    c = meshpde.correct(V, F, [0], ["0,0,1", "0.3,-0.2,0.5"], points=[point], radius=R, laplacian="cotan",
                        allow_intersections=True)
    P = s.positions(moves)
    assert np.abs(c.V - P).max() <= 1e-9
    # Each handle's point lands on its move (read where the session says it reads it).
    for reading, move in zip(s.readings, moves):
        at = sum(w * (P[v] - V[v]) for v, w in reading)
        assert np.abs(at - move).max() <= 1e-9
    forces = s.forces(moves)
    assert forces.shape == (2, 3) and np.isfinite(forces).all() and np.abs(forces).max() > 0
    assert np.abs(s.forces(2 * moves) - 2 * forces).max() <= 1e-9 * np.abs(forces).max()
    # Only points: the handles are the points' nearest corners.
    only = meshpde.DragSession(V, F, points=[point], radius=R)
    assert len(only.handles) == 1
    with pytest.raises(meshpde.InputError, match="smooth boundary"):
        meshpde.DragSession(V, F, [0], radius=R, points=[point], boundary="clamp")
    with pytest.raises(meshpde.InputError, match="handles"):
        meshpde.DragSession(V, F, radius=R)
    # A point farther off the surface than the region reaches is warned about (as correct() does).
    with pytest.warns(UserWarning, match=r"points\[0\] .* farther than the region's radius 4"):
        meshpde.DragSession(V, F, points=[3 * point], radius=R)


def test_global_solver_equals_a_direct_solve():
    V, F = meshpde.generate.icosphere(4)
    held = np.flatnonzero(V[:, 2] < -0.5)
    free = np.setdiff1d(np.arange(len(V)), held)
    u = np.zeros(len(V))
    u[held] = V[held, 0]
    g = meshpde.GlobalBilaplacianSolver(V, F, free, tolerance=1e-12)
    x, info = g.solve(u)
    K, M = meshpde.stiffness(V, F), meshpde.mass(V, F)
    ref = dirichlet_solve(K @ sp.diags(1 / M.diagonal()) @ K, held, u[held])
    assert info["converged"] and np.abs(x - ref).max() <= 1e-8 * np.abs(ref).max()
    x2, info2 = g.solve(2 * u)
    assert np.abs(x2 - 2 * x).max() <= 1e-8 * np.abs(x).max()
    assert g.multigrid_builds + g.factorizations == 1  # the preconditioner was kept
