// meshpde's stateful classes in Python, with the C++ names: PdeSession,
// HapticSession, DragSession and GlobalBilaplacianSolver. Each Python object owns its
// mesh and operators (the C++ classes keep references to them), declared before the
// session so that the session is destroyed first.
#include <fmt/format.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <memory>

#include "bindings.h"
#include "convert.h"
#include "meshpde/apps/haptics.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "meshpde/pde/pde_session.h"

namespace meshpde::python {

namespace {

py::dict step_result(const StepResult& r) {
  py::dict d;
  d["iterations"] = r.cg.iterations;
  d["relative_residual"] = r.cg.relative_residual;
  d["converged"] = r.cg.converged();
  d["message"] = r.cg.message;
  d["free_vertices"] = r.free_vertices;
  d["grown"] = r.grown;
  d["shrunk"] = r.shrunk;
  return d;
}

struct PyPdeSession {
  Mesh mesh;
  FemOperators ops;
  std::unique_ptr<PdeSession> s;

  PyPdeSession(const py::handle& V, const py::handle& F, int components, const PdeCoefficients& c,
               const DomainOptions& d)
      : mesh(mesh_arg(V, F)), ops(build_cotan_operators(mesh)) {
    if (components < 1) throw InputError(fmt::format("components: expected >= 1, got {}", components));
    s = std::make_unique<PdeSession>(mesh, ops, components, c, d);
  }
  Field optional_field(const py::handle& f) const {
    return f.is_none() ? Field() : field_arg(f, "f", mesh.num_vertices(), s->components());
  }
};

struct PyHapticSession {
  MeshOperators mo;  // on the intrinsic connectivity when asked for (same vertices)
  std::unique_ptr<HapticSession> s;
  PyHapticSession(const py::handle& V, const py::handle& F, const HapticParams& p, LaplacianKind kind)
      : mo(build_mesh_operators(mesh_arg(V, F), kind)), s(std::make_unique<HapticSession>(mo.mesh, mo.ops, p)) {}
};

struct PyDragSession {
  Mesh mesh;
  FemOperators ops;
  std::unique_ptr<DragSession> s;
  Eigen::MatrixXd handle_displacements(const py::handle& d) const {
    return Eigen::MatrixXd(field_arg(d, "handle_displacements", static_cast<Eigen::Index>(s->handles().size()), 3));
  }
};

struct PyGlobalSolver {
  Mesh mesh;
  FemOperators ops;
  std::unique_ptr<GlobalBilaplacianSolver> s;
};

GlobalBilaplacianParams::Preconditioner preconditioner_arg(const std::string& name) {
  using P = GlobalBilaplacianParams::Preconditioner;
  if (name == "auto") return P::Auto;
  if (name == "multigrid") return P::Multigrid;
  if (name == "laplacian_factor") return P::LaplacianFactor;
  throw InputError(fmt::format("preconditioner: expected 'auto', 'multigrid' or 'laplacian_factor', got '{}'", name));
}

}  // namespace

void bind_sessions(py::module_& m) {
  const PdeCoefficients c0;
  const DomainOptions d0;
  py::class_<PyPdeSession>(
      m, "PdeSession",
      R"doc(PdeSession(V, F, components=1, alpha=0, b1=1, b2=0, g0=0, g1=1, g2=0, self_adjusting=False, ...)

alpha M u'' + (b1 M + b2 Kt) u' + Kt u = f, Kt = g0 M + g1 K + g2 K M^-1 K, stepped by
backward Euler with CG on the free vertices of an active domain (every vertex frozen
at first: activate_all(), activate_rings(), or constrain() which frees rings around a
vertex). values and velocities are (n, components); reaction_forces one row per
constrained vertex (the force the constraint applies to hold it).)doc")
      .def(py::init([](const ArrayLike& V, const ArrayLike& F, int components, double alpha, double b1, double b2,
                       double g0, double g1, double g2, bool self_adjusting, double grow_fraction, double rest_value,
                       double rest_rate, int rest_steps, int seed_rings, int max_free, double tolerance,
                       int max_iterations) {
             auto p = std::make_unique<PyPdeSession>(
                 V, F, components, PdeCoefficients{alpha, b1, b2, g0, g1, g2},
                 DomainOptions{self_adjusting, grow_fraction, rest_value, rest_rate, rest_steps, seed_rings, max_free});
             p->s->cg_options.tolerance = tolerance;
             p->s->cg_options.max_iterations = max_iterations;
             return p;
           }),
           py::arg("V"), py::arg("F"), py::arg("components") = 1, py::arg("alpha") = c0.alpha, py::arg("b1") = c0.b1,
           py::arg("b2") = c0.b2, py::arg("g0") = c0.g0, py::arg("g1") = c0.g1, py::arg("g2") = c0.g2,
           py::arg("self_adjusting") = d0.self_adjusting, py::arg("grow_fraction") = d0.grow_fraction,
           py::arg("rest_value") = d0.rest_value, py::arg("rest_rate") = d0.rest_rate,
           py::arg("rest_steps") = d0.rest_steps, py::arg("seed_rings") = d0.seed_rings,
           py::arg("max_free") = d0.max_free, py::arg("tolerance") = CgOptions{}.tolerance,
           py::arg("max_iterations") = CgOptions{}.max_iterations)
      .def_property_readonly("components", [](const PyPdeSession& p) { return p.s->components(); })
      .def_property_readonly("values", [](const PyPdeSession& p) { return to_numpy(p.s->values()); })
      .def_property_readonly("velocities", [](const PyPdeSession& p) { return to_numpy(p.s->velocities()); })
      .def(
          "set_values",
          [](PyPdeSession& p, const ArrayLike& u, bool as_rest) {
            p.s->set_values(field_arg(u, "u", p.mesh.num_vertices(), p.s->components()), as_rest);
          },
          py::arg("u"), py::arg("as_rest") = true)
      .def(
          "set_velocities",
          [](PyPdeSession& p, const ArrayLike& v) {
            p.s->set_velocities(field_arg(v, "v", p.mesh.num_vertices(), p.s->components()));
          },
          py::arg("v"))
      .def(
          "constrain",
          [](PyPdeSession& p, long long v, const ArrayLike& value) {
            const int i = vertex_arg(v, "vertex", p.mesh.num_vertices());
            const Eigen::VectorXd x = py::isinstance<py::float_>(value) || py::isinstance<py::int_>(value)
                                          ? Eigen::VectorXd::Constant(1, value.cast<double>())
                                          : vector_arg(value, "value", p.s->components());
            if (x.size() != p.s->components())
              throw InputError(fmt::format("value: expected {} components, got {}", p.s->components(), x.size()));
            if (!std::isfinite(x[0])) throw InputError("value: not finite");
            p.s->constrain(i, std::span<const double>(x.data(), static_cast<std::size_t>(x.size())));
          },
          py::arg("vertex"), py::arg("value"))
      .def(
          "release", [](PyPdeSession& p, long long v) { p.s->release(vertex_arg(v, "vertex", p.mesh.num_vertices())); },
          py::arg("vertex"))
      .def_property_readonly("constrained_vertices",
                             [](const PyPdeSession& p) {
                               const auto c = p.s->constrained_vertices();
                               return to_numpy(std::vector<int>(c.begin(), c.end()));
                             })
      .def_property_readonly("reaction_forces", [](const PyPdeSession& p) { return to_numpy(p.s->reaction_forces()); })
      .def_property_readonly("free_vertices",
                             [](const PyPdeSession& p) {
                               const auto f = p.s->domain().free_vertices();
                               return to_numpy(std::vector<int>(f.begin(), f.end()));
                             })
      .def(
          "activate",
          [](PyPdeSession& p, const ArrayLike& vertices) {
            const std::vector<int> v = vertices_arg(vertices, "vertices", p.mesh.num_vertices());
            p.s->activate(v);
          },
          py::arg("vertices"))
      .def("activate_all", [](PyPdeSession& p) { p.s->activate_all(); })
      .def(
          "activate_rings",
          [](PyPdeSession& p, long long v, int k) {
            if (k < 0) throw InputError("rings: expected >= 0");
            p.s->activate_rings(vertex_arg(v, "vertex", p.mesh.num_vertices()), k);
          },
          py::arg("vertex"), py::arg("rings"))
      .def("deactivate_all", [](PyPdeSession& p) { p.s->deactivate_all(); })
      .def(
          "step",
          [](PyPdeSession& p, double dt, const ArrayLike& f) {
            if (!(dt > 0) || !std::isfinite(dt)) throw InputError(fmt::format("dt: expected > 0, got {}", dt));
            const Field force = p.optional_field(f);
            StepResult r;
            {
              py::gil_scoped_release release;
              r = p.s->step(dt, force.size() ? &force : nullptr);
            }
            return step_result(r);
          },
          py::arg("dt"), py::arg("f") = py::none())
      .def(
          "solve_steady",
          [](PyPdeSession& p, const ArrayLike& f) {
            const Field force = p.optional_field(f);
            StepResult r;
            {
              py::gil_scoped_release release;
              r = p.s->solve_steady(force.size() ? &force : nullptr);
            }
            return step_result(r);
          },
          py::arg("f") = py::none());

  const HapticParams h0;
  py::class_<PyHapticSession>(
      m, "HapticSession",
      R"doc(HapticSession(V, F, influence=0, stiffness=1, ..., solver="factored", wait_for_factors=False, laplacian="auto")

A probe holds a vertex (touch) and moves (move_probe, an offset in mesh units); each
step(dt) returns the force felt by the probe (3,), pushing back out of a dent. start()
runs the steps on a servo thread at rate_hz; log() returns every step. influence: the
decay length of a poke (0: 3 mean edge lengths). solver: "factored" (each step two
triangular sweeps with a factor of the active domain, rebuilt on a second thread: a
bounded step) or "cg" (Jacobi-CG every step). wait_for_factors=True: step() waits for a
factor being built; set it when stepping faster than real time (a notebook loop, an
offline replay): the domain then keeps up and the forces are the same in every run.
laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes), "cotan"
or "intrinsic".)doc")
      .def(py::init([](const ArrayLike& V, const ArrayLike& F, double influence, double stiffness, double mass,
                       double damping, double stiffness_damping, double domain_tolerance, double rate_hz,
                       const std::string& solver, bool wait_for_factors, const std::string& laplacian) {
             HapticParams p;
             p.wait_for_factors = wait_for_factors;
             if (solver == "factored")
               p.solver = HapticSolver::Factored;
             else if (solver == "cg")
               p.solver = HapticSolver::Cg;
             else
               throw InputError(fmt::format("solver: expected 'factored' or 'cg', got '{}'", solver));
             p.influence = influence;
             p.stiffness = stiffness;
             p.mass = mass;
             p.damping = damping;
             p.stiffness_damping = stiffness_damping;
             p.domain_tolerance = domain_tolerance;
             p.rate_hz = rate_hz;
             return std::make_unique<PyHapticSession>(V, F, p, parse_laplacian_kind(laplacian));
           }),
           py::arg("V"), py::arg("F"), py::arg("influence") = h0.influence, py::arg("stiffness") = h0.stiffness,
           py::arg("mass") = h0.mass, py::arg("damping") = h0.damping,
           py::arg("stiffness_damping") = h0.stiffness_damping, py::arg("domain_tolerance") = h0.domain_tolerance,
           py::arg("rate_hz") = h0.rate_hz, py::arg("solver") = "factored",
           py::arg("wait_for_factors") = h0.wait_for_factors, py::arg("laplacian") = "auto")
      .def(
          "touch",
          [](PyHapticSession& p, long long v) { p.s->touch(vertex_arg(v, "vertex", p.mo.mesh.num_vertices())); },
          py::arg("vertex"))
      .def(
          "touch_point", [](PyHapticSession& p, const ArrayLike& x) { p.s->touch_point(vector_arg(x, "point", 3)); },
          py::arg("point"))
      .def(
          "move_probe", [](PyHapticSession& p, const ArrayLike& x) { p.s->move_probe(vector_arg(x, "offset", 3)); },
          py::arg("offset"))
      .def("release", [](PyHapticSession& p) { p.s->release(); })
      .def_property_readonly("touching", [](const PyHapticSession& p) { return p.s->touching(); })
      .def_property_readonly("contact_vertex", [](const PyHapticSession& p) { return p.s->contact_vertex(); })
      .def(
          "step",
          [](PyHapticSession& p, double dt) {
            if (!(dt > 0) || !std::isfinite(dt)) throw InputError(fmt::format("dt: expected > 0, got {}", dt));
            Eigen::Vector3d f;
            {
              py::gil_scoped_release release;
              f = p.s->step(dt);
            }
            return to_numpy(Eigen::VectorXd(f));
          },
          py::arg("dt"))
      .def("start", [](PyHapticSession& p) { p.s->start(); })
      .def("stop",
           [](PyHapticSession& p) {
             py::gil_scoped_release release;
             p.s->stop();
           })
      .def_property_readonly("running", [](const PyHapticSession& p) { return p.s->running(); })
      .def_property_readonly("latest_force",
                             [](const PyHapticSession& p) { return to_numpy(Eigen::VectorXd(p.s->latest_force())); })
      .def_property_readonly("displacement", [](const PyHapticSession& p) { return to_numpy(p.s->displacement()); })
      .def_property_readonly("active_vertices", [](const PyHapticSession& p) { return p.s->active_vertices(); })
      .def_property_readonly("misses", [](const PyHapticSession& p) { return p.s->misses(); })
      .def_property_readonly("factorizations", [](const PyHapticSession& p) { return p.s->factorizations(); })
      .def(
          "log",
          [](const PyHapticSession& p) {
            const std::vector<HapticSample> log = p.s->log();
            const auto n = static_cast<Eigen::Index>(log.size());
            Eigen::VectorXd t(n), latency(n), free(n), iters(n), missed(n), factored(n), new_factor(n);
            Eigen::MatrixXd phases(n, 4);  // install, solve, propose, publish (us)
            Eigen::MatrixXd probe(n, 3), force(n, 3);
            for (Eigen::Index i = 0; i < n; ++i) {
              const HapticSample& s = log[static_cast<std::size_t>(i)];
              t[i] = s.time;
              probe.row(i) = s.probe.transpose();
              force.row(i) = s.force.transpose();
              latency[i] = s.latency_us;
              free[i] = s.free_vertices;
              iters[i] = s.cg_iterations;
              missed[i] = s.missed;
              factored[i] = s.factored;
              new_factor[i] = s.new_factor;
              phases.row(i) << s.install_us, s.solve_us, s.propose_us, s.publish_us;
            }
            py::dict d;
            d["time"] = to_numpy(t);
            d["probe"] = to_numpy(probe);
            d["force"] = to_numpy(force);
            d["latency_us"] = to_numpy(latency);
            d["free_vertices"] = to_numpy(free);
            d["cg_iterations"] = to_numpy(iters);
            d["missed"] = to_numpy(missed);
            d["factored"] = to_numpy(factored);
            d["new_factor"] = to_numpy(new_factor);
            const char* names[] = {"install_us", "solve_us", "propose_us", "publish_us"};
            for (int k = 0; k < 4; ++k) d[names[k]] = to_numpy(Eigen::VectorXd(phases.col(k)));
            return d;
          },
          R"doc(The steps so far, one array entry a step: time (s), probe and force (n x 3),
latency_us, free_vertices, cg_iterations, missed, factored, new_factor (the step took a
new domain's factor), and where each step's time went: install_us, solve_us,
propose_us, publish_us.)doc");

  const DragSessionParams g0;
  py::class_<PyDragSession>(
      m, "DragSession",
      R"doc(DragSession(V, F, handles=None, radius=0, rings=0, g1=0, g2=1, boundary="smooth", margin=False, inner_margin=False, points=None, handle_radius=None)

Interactive drags of handles over one region with one factorization:
positions(d) for handle displacements d (k, 3) costs a product, not a solve;
add_handle, grow and shrink reuse the factor where they can. Handles: vertices
(`handles`) and surface points (`points`, (k, 3) positions in V's coordinates: the
surface point nearest each), the vertices' first in d. The region: the vertices
within `radius` of the handles on the surface (geodesic_distance), or `rings` rings
of neighbours of the first; held at zero outside. boundary="smooth" (the default for
a radius) ends it as correct() does, displacement and slope zero at the radius, with
handles of `handle_radius` (default None: a quarter of the radius; 0: a vertex held,
a point a point load), so a drag equals correct(..., laplacian="cotan") with the same
handles and size; "clamp" holds the field at zero just outside (the rule before;
margins, grow and shrink need it; vertex handles of size 0 only).)doc")
      .def(py::init([](const ArrayLike& V, const ArrayLike& F, const py::object& handles, double radius, int rings,
                       double g1, double g2, const std::string& boundary, bool margin, bool inner_margin,
                       const py::object& points, const py::object& handle_radius) {
             auto p = std::make_unique<PyDragSession>();
             p->mesh = mesh_arg(V, F);
             p->ops = build_cotan_operators(p->mesh);
             const std::vector<int> h =
                 handles.is_none() ? std::vector<int>() : vertices_arg(handles, "handles", p->mesh.num_vertices());
             std::vector<SurfacePoint> at;
             if (!points.is_none()) {
               const std::vector<Eigen::Vector3d> xyz = points_arg(points, "points");
               at = with_warnings([&] {
                 std::vector<SurfacePoint> found = closest_surface_points(p->mesh, xyz);
                 // As correct() warns about its handle points: one farther off the surface
                 // than the region reaches was probably given in another frame or unit.
                 for (std::size_t k = 0; k < xyz.size(); ++k)
                   if (const double off = (position(p->mesh, found[k]) - xyz[k]).norm(); radius > 0 && off > radius)
                     warn(
                         fmt::format("points[{}] ({:g}, {:g}, {:g}) lies {:.3g} from the surface, farther than the "
                                     "region's radius {:g}: its handle is the nearest surface point; is it in the "
                                     "mesh's frame and unit?",
                                     k, xyz[k].x(), xyz[k].y(), xyz[k].z(), off, radius));
                 return found;
               });
             }
             if (h.empty() && at.empty()) throw InputError("give handles: vertices, points, or both");
             DragSessionParams q{.radius = radius,
                                 .handle_radius = handle_radius.is_none() ? -1.0 : handle_radius.cast<double>(),
                                 .rings = rings,
                                 .g1 = g1,
                                 .g2 = g2,
                                 .boundary = parse_region_boundary(boundary),
                                 .margin = margin,
                                 .inner_margin = inner_margin};
             {
               py::gil_scoped_release release;
               p->s = std::make_unique<DragSession>(p->mesh, p->ops, h, at, q);
             }
             return p;
           }),
           py::arg("V"), py::arg("F"), py::arg("handles") = py::none(), py::arg("radius") = g0.radius,
           py::arg("rings") = g0.rings, py::arg("g1") = g0.g1, py::arg("g2") = g0.g2,
           py::arg("boundary") = to_string(g0.boundary), py::arg("margin") = g0.margin,
           py::arg("inner_margin") = g0.inner_margin, py::arg("points") = py::none(),
           py::arg("handle_radius") = py::none())
      .def(
          "displacements",
          [](const PyDragSession& p, const ArrayLike& d) {
            return to_numpy(Eigen::MatrixXd(p.s->displacements(p.handle_displacements(d))));
          },
          py::arg("handle_displacements"))
      .def(
          "positions",
          [](const PyDragSession& p, const ArrayLike& d) {
            return to_numpy(Eigen::MatrixXd(p.s->positions(p.handle_displacements(d))));
          },
          py::arg("handle_displacements"))
      .def(
          "add_handle",
          [](PyDragSession& p, long long v) {
            const int i = vertex_arg(v, "vertex", p.mesh.num_vertices());
            py::gil_scoped_release release;
            p.s->add_handle(i);
          },
          py::arg("vertex"))
      .def(
          "grow",
          [](PyDragSession& p, int rings) {
            if (rings < 1) throw InputError("rings: expected >= 1");
            py::gil_scoped_release release;
            p.s->grow(rings);
          },
          py::arg("rings") = 1)
      .def(
          "shrink",
          [](PyDragSession& p, int rings) {
            if (rings < 1) throw InputError("rings: expected >= 1");
            py::gil_scoped_release release;
            p.s->shrink(rings);
          },
          py::arg("rings") = 1)
      .def(
          "forces",
          [](const PyDragSession& p, const ArrayLike& d) {
            return to_numpy(Eigen::MatrixXd(p.s->forces(p.handle_displacements(d))));
          },
          py::arg("handle_displacements"),
          "The force on each handle that puts it on its displacement (k, 3): a sized or point handle's load's "
          "total, a held vertex's row of the system applied to the field")
      .def_property_readonly(
          "handles", [](const PyDragSession& p) { return to_numpy(p.s->handles()); },
          "The handles' vertices (a point's: its triangle's nearest corner)")
      .def_property_readonly(
          "readings",
          [](const PyDragSession& p) {
            py::list out;
            for (const auto& reading : p.s->readings()) {
              py::list one;
              for (const auto& [v, w] : reading) one.append(py::make_tuple(v, w));
              out.append(one);
            }
            return out;
          },
          "Per handle, where its displacement is read: (vertex, weight) pairs")
      .def_property_readonly(
          "handle_radius", [](const PyDragSession& p) { return p.s->handle_radius(); },
          "The handles' size in use (mm; 0: a held vertex or a point load)")
      .def_property_readonly("region", [](const PyDragSession& p) { return to_numpy(p.s->region()); })
      .def_property_readonly(
          "boundary", [](const PyDragSession& p) { return std::string(to_string(p.s->boundary())); },
          "'smooth' or 'clamp': the boundary in use (a region given by rings ends by the clamp)")
      .def_property_readonly("basis", [](const PyDragSession& p) { return to_numpy(p.s->basis()); })
      .def_property_readonly("factorizations", [](const PyDragSession& p) { return p.s->factorizations(); });

  const GlobalBilaplacianParams q0;
  py::class_<PyGlobalSolver>(
      m, "GlobalBilaplacianSolver",
      R"doc(GlobalBilaplacianSolver(V, F, free, g1=0, g2=1, tolerance=1e-8, max_iterations=1000, preconditioner="auto")

Whole-mesh steady solves (g1 K + g2 K M^-1 K) u = 0 on the `free` vertices, the others
held at the values given to solve(u) (n,) or (n, c). The preconditioner (surface
multigrid or Laplacian factor, "auto" chooses by measured convergence) is built by the
first solve and kept. Returns (u, info).)doc")
      .def(py::init([](const ArrayLike& V, const ArrayLike& F, const ArrayLike& free, double g1, double g2,
                       double tolerance, int max_iterations, const std::string& preconditioner) {
             auto p = std::make_unique<PyGlobalSolver>();
             p->mesh = mesh_arg(V, F);
             p->ops = build_cotan_operators(p->mesh);
             GlobalBilaplacianParams q;
             q.g1 = g1;
             q.g2 = g2;
             q.tolerance = tolerance;
             q.max_iterations = max_iterations;
             q.preconditioner = preconditioner_arg(preconditioner);
             std::vector<int> f = vertices_arg(free, "free", p->mesh.num_vertices());
             p->s = std::make_unique<GlobalBilaplacianSolver>(p->mesh, p->ops, std::move(f), q);
             return p;
           }),
           py::arg("V"), py::arg("F"), py::arg("free"), py::arg("g1") = q0.g1, py::arg("g2") = q0.g2,
           py::arg("tolerance") = q0.tolerance, py::arg("max_iterations") = q0.max_iterations,
           py::arg("preconditioner") = "auto")
      .def(
          "solve",
          [](PyGlobalSolver& p, const ArrayLike& u, bool warm_start) {
            const Field held = field_arg(u, "u", p.mesh.num_vertices());
            GlobalBilaplacianResult r;
            {
              py::gil_scoped_release release;
              r = p.s->solve(held, warm_start);
            }
            py::dict info;
            info["iterations"] = r.iterations;
            info["relative_residual"] = r.relative_residual;
            info["converged"] = r.converged;
            info["preconditioner"] =
                r.used == GlobalBilaplacianParams::Preconditioner::Multigrid ? "multigrid" : "laplacian_factor";
            info["multigrid_iterations"] = r.multigrid_iterations;
            info["setup_seconds"] = r.setup_seconds;
            info["solve_seconds"] = r.solve_seconds;
            info["bytes_per_vertex"] = r.bytes_per_vertex;
            const bool column = u.is_none() ? false : py::array::ensure(u).ndim() == 1;
            py::object values =
                column ? py::object(to_numpy(Eigen::VectorXd(r.values.col(0)))) : py::object(to_numpy(r.values));
            return py::make_tuple(values, info);
          },
          py::arg("u"), py::arg("warm_start") = false)
      .def_property_readonly("multigrid_builds", [](const PyGlobalSolver& p) { return p.s->multigrid_builds(); })
      .def_property_readonly("factorizations", [](const PyGlobalSolver& p) { return p.s->factorizations(); });

  // Same-run C++ baselines for bench/python/bench_python.py (not part of the API).
  py::module_ b = m.def_submodule("_bench", "C++ loops timed for the Python benchmarks");
  b.def(
      "poke_step_us",
      [](PyPdeSession& p, long long vertex, const py::handle& direction, double depth, int steps, double dt) {
        const int v = vertex_arg(vertex, "vertex", p.mesh.num_vertices());
        const Eigen::Vector3d n = vector_arg(direction, "direction", 3);
        std::vector<double> us(static_cast<std::size_t>(std::max(steps, 0)));
        py::gil_scoped_release release;
        for (int k = 0; k < steps; ++k) {
          const Eigen::Vector3d target = depth * std::sin(M_PI * (k + 1) / steps) * n;
          const auto t = std::chrono::steady_clock::now();
          p.s->constrain(v, std::span<const double>(target.data(), 3));
          p.s->step(dt);
          us[static_cast<std::size_t>(k)] =
              std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t).count();
        }
        return us;
      },
      py::arg("session"), py::arg("vertex"), py::arg("direction"), py::arg("depth"), py::arg("steps"), py::arg("dt"));
  b.def(
      "stiffness_seconds",
      [](const ArrayLike& V, const ArrayLike& F) {
        const Positions P = positions_arg(V);
        const Triangles T = triangles_arg(F, P.rows());
        py::gil_scoped_release release;
        const auto t = std::chrono::steady_clock::now();
        const Mesh mesh(P, T);
        const Eigen::SparseMatrix<double> K = stiffness_matrix(mesh, build_cotan_operators(mesh));
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
        return K.nonZeros() > 0 ? s : -1.0;
      },
      py::arg("V"), py::arg("F"));
}

}  // namespace meshpde::python
