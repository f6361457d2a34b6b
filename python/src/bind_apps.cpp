// meshpde's applications in Python: heat and wave, fairing, interpolation and vessel
// correction. Each call converts its arguments, releases the GIL for the library's
// work, and returns numpy arrays or a small result object.
#include <fmt/format.h>
#include <pybind11/functional.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "bindings.h"
#include "convert.h"
#include "meshpde/apps/fairing.h"
#include "meshpde/apps/heat_wave.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/selection.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/caps.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/laplacian.h"
#ifdef MESHPDE_HAVE_MEDICAL
#include "meshpde/io/medical_io.h"
#endif

namespace meshpde::python {

namespace {

// {vertex: value} or [(vertex, value), ...].
std::vector<std::pair<int, double>> vertex_values_arg(const py::handle& obj, const char* name, Eigen::Index nv) {
  std::vector<std::pair<int, double>> out;
  if (obj.is_none()) return out;
  auto add = [&](const py::handle& k, const py::handle& v) {
    long long vertex = 0;
    double value = 0;
    try {
      vertex = k.cast<long long>();
      value = v.cast<double>();
    } catch (const py::cast_error&) {
      throw InputError(fmt::format("{}: expected vertex -> number pairs", name));
    }
    if (!std::isfinite(value)) throw InputError(fmt::format("{}: value at vertex {} is not finite", name, vertex));
    out.emplace_back(vertex_arg(vertex, name, nv), value);
  };
  if (py::isinstance<py::dict>(obj)) {
    for (const auto& [k, v] : obj.cast<py::dict>()) add(k, v);
    return out;
  }
  for (const auto& item : obj) {
    const py::sequence pair = py::reinterpret_borrow<py::sequence>(item);
    if (!py::isinstance<py::sequence>(item) || pair.size() != 2)
      throw InputError(fmt::format("{}: expected a dict or a list of (vertex, value) pairs", name));
    add(pair[0], pair[1]);
  }
  return out;
}

// "scalar", "displacement" or "tangent", as interpolate() and InterpolationSolver take it.
FieldKind field_kind_arg(const std::string& kind) {
  if (kind == "scalar") return FieldKind::Scalar;
  if (kind == "displacement") return FieldKind::Displacement;
  if (kind == "tangent") return FieldKind::Tangent;
  throw InputError(fmt::format("kind: expected 'scalar', 'displacement' or 'tangent', got '{}'", kind));
}

SteadySolver solver_arg(const std::string& name) {
  return parse_steady_solver(name);  // (a bad name: InputError, a ValueError)
}

// Vertex indices, or selection specs as `meshpde fair --fixed` takes them ("boundary",
// "rings:V:K", "radius:V:R", "halfspace:NX,NY,NZ:D", "all", ...).
std::vector<int> selection_arg(const Mesh& mesh, const py::handle& obj, const char* name) {
  if (py::isinstance<py::str>(obj))
    return with_warnings([&] { return select_vertices(mesh, obj.cast<std::string>()); });
  if (py::isinstance<py::list>(obj) || py::isinstance<py::tuple>(obj)) {
    const py::sequence seq = py::reinterpret_borrow<py::sequence>(obj);
    if (seq.size() > 0 && py::isinstance<py::str>(seq[0]))
      return with_warnings([&] { return select_vertices(mesh, seq.cast<std::vector<std::string>>()); });
  }
  return vertices_arg(obj, name, mesh.num_vertices());
}

py::object propagation_result(const PropagationResult& r) {
  py::dict d;
  d["values"] = to_numpy(r.values);
  d["velocity"] = to_numpy(r.velocity);
  d["cg_iterations"] = r.cg_iterations;
  d["max_free_vertices"] = r.max_free_vertices;
  return py::module_::import("types").attr("SimpleNamespace")(**d);
}

py::object run_propagation(Propagation eq, const py::handle& V, const py::handle& F, const py::handle& sources,
                           const py::handle& flux, const py::handle& impulses, double dt, int steps, double diffusivity,
                           double speed, double damping, const py::handle& initial, const py::handle& initial_velocity,
                           bool local, const std::string& laplacian, const py::object& callback) {
  const Mesh mesh = mesh_arg(V, F);
  const LaplacianKind kind = parse_laplacian_kind(laplacian);
  const Eigen::Index nv = mesh.num_vertices();
  PropagationParams p{.equation = eq,
                      .dt = dt,
                      .steps = steps,
                      .diffusivity = diffusivity,
                      .wave_speed = speed,
                      .damping = damping,
                      .local = local};
  p.fixed = vertex_values_arg(sources, "sources", nv);
  p.flux = vertex_values_arg(flux, "flux", nv);
  if (!initial.is_none()) p.initial = vector_arg(initial, "initial", nv);
  if (!initial_velocity.is_none()) p.initial_velocity = vector_arg(initial_velocity, "initial_velocity", nv);
  if (!impulses.is_none()) {
    if (p.initial_velocity.size() == 0) p.initial_velocity = Eigen::VectorXd::Zero(nv);
    for (const auto& [v, x] : vertex_values_arg(impulses, "impulses", nv)) p.initial_velocity[v] += x;
  }
  if (!callback.is_none() && !PyCallable_Check(callback.ptr())) throw py::type_error("callback: expected a callable");
  PropagationResult r;
  {
    py::gil_scoped_release release;
    const MeshOperators mo = build_mesh_operators(mesh, kind);
    r = propagate(mo.mesh, mo.ops, p, [&](int step, const Eigen::VectorXd& u, const Eigen::VectorXd& ut) {
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (!callback.is_none()) callback(step, to_numpy(u), to_numpy(ut));
    });
  }
  return propagation_result(r);
}

// The correction's options, by the names of `meshpde correct`'s flags.
struct CorrectionOptions {
  CorrectionParams params;
  std::string method = "fem";
  std::string solver = "auto";
  std::string units_warning;  // the mesh looks unlike a vessel in params.units
  CorrectionCaps caps;        // the rule, and the caps it found, for the report
};

Volume volume_arg(const py::handle& image) {
  if (py::isinstance<py::tuple>(image)) {
    const py::tuple t = image.cast<py::tuple>();
    if (t.size() != 2) throw InputError("image: expected a path or a (values, affine) tuple");
    const py::array_t<float, py::array::f_style | py::array::forcecast> a =
        py::array_t<float, py::array::f_style | py::array::forcecast>::ensure(t[0]);
    if (!a || a.ndim() != 3) throw InputError("image: values must be a 3-D array indexed [i, j, k]");
    const Field A = field_arg(t[1], "image affine", 4, 4);
    Volume v;
    v.dims = {static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), static_cast<int>(a.shape(2))};
    const Eigen::Matrix3d L = A.topLeftCorner(3, 3);
    for (int c = 0; c < 3; ++c) v.spacing[c] = L.col(c).norm();
    if (!(v.spacing.minCoeff() > 0)) throw InputError("image affine: a voxel axis has zero length");
    v.direction = L * v.spacing.cwiseInverse().asDiagonal();
    v.origin = A.topRightCorner(3, 1);
    v.values.assign(a.data(), a.data() + a.size());
    v.name = "image";
    v.validate();
    return v;
  }
#ifdef MESHPDE_HAVE_MEDICAL
  return read_volume(image.cast<std::filesystem::path>());
#else
  throw InputError("image: reading a volume file needs meshpde built with meshpde::medical (VTK)");
#endif
}

CorrectionOptions correction_options(const Mesh& mesh, const py::handle& vertices, const py::handle& moves,
                                     const py::dict& o) {
  CorrectionOptions c;
  CorrectionParams& p = c.params;
  auto get = [&](const char* key) -> py::object { return o.contains(key) ? o[key] : py::object(py::none()); };
  // Handle vertices: indices, or "@X,Y,Z" (the nearest vertex) as the command line takes them.
  std::vector<int> handles;
  std::vector<std::optional<Eigen::Vector3d>> spelled_at;  // per handle: the @X,Y,Z point
  if (!vertices.is_none()) {
    const bool listed = py::isinstance<py::list>(vertices) || py::isinstance<py::tuple>(vertices);
    bool spelled = py::isinstance<py::str>(vertices);
    if (listed)
      for (const py::handle x : py::reinterpret_borrow<py::sequence>(vertices))
        spelled = spelled || py::isinstance<py::str>(x);
    if (spelled) {
      const py::tuple vs = py::isinstance<py::str>(vertices) ? py::make_tuple(vertices)
                                                             : py::tuple(py::reinterpret_borrow<py::object>(vertices));
      for (const py::handle x : vs) {
        const bool text = py::isinstance<py::str>(x);
        const std::string spec = text ? x.cast<std::string>() : std::string();
        const WarningCollector handled;  // a far @X,Y,Z: the correction's handle_warning says it
        handles.push_back(text ? parse_vertex_spec(mesh, spec)
                               : vertex_arg(x.cast<long long>(), "vertices", mesh.num_vertices()));
        spelled_at.push_back(spec.starts_with('@') ? std::optional(parse_point_spec(spec.substr(1))) : std::nullopt);
      }
    } else {
      handles = vertices_arg(vertices, "vertices", mesh.num_vertices());
    }
  }
  // Handle points: (k, 3) positions in V's coordinates; each is the surface point nearest to it.
  std::vector<Eigen::Vector3d> points;
  if (const py::object v = get("points"); !v.is_none()) points = points_arg(v, "points");
  if (handles.empty() && points.empty()) throw InputError("give handles: vertices, points, or both");
  if (moves.is_none() || !py::isinstance<py::sequence>(moves) || py::isinstance<py::str>(moves))
    throw InputError("moves: expected one move per handle: (dx, dy, dz) or 'normal:D'");
  const py::sequence seq = py::reinterpret_borrow<py::sequence>(moves);
  if (seq.size() != handles.size() + points.size())
    throw InputError(
        fmt::format("moves: {} moves for {} vertices and {} points: give one move per handle "
                    "(the vertices' first, then the points')",
                    seq.size(), handles.size(), points.size()));
  for (std::size_t k = 0; k < seq.size(); ++k) {
    const py::handle mv = seq[k];
    const bool is_point = k >= handles.size();
    std::string text;
    if (py::isinstance<py::str>(mv)) {
      text = mv.cast<std::string>();
    } else {
      const Eigen::VectorXd d = vector_arg(mv, fmt::format("moves[{}]", k).c_str(), 3);
      text = fmt::format("{:.17g},{:.17g},{:.17g}", d[0], d[1], d[2]);
    }
    if (is_point)
      p.handles.push_back(parse_point_handles(mesh, {points[k - handles.size()]}, {text})[0]);
    else {
      p.handles.push_back(parse_handles(mesh, {handles[k]}, {text})[0]);
      if (k < spelled_at.size()) p.handles.back().given = spelled_at[k];
    }
  }
  if (const py::object v = get("handle_radius"); !v.is_none()) p.handle_radius = v.cast<double>();
  auto num = [&](const char* key, double& x) {
    if (const py::object v = get(key); !v.is_none()) x = v.cast<double>();
  };
  auto integer = [&](const char* key, int& x) {
    if (const py::object v = get(key); !v.is_none()) x = v.cast<int>();
  };
  if (const py::object v = get("units"); !v.is_none()) p.units = parse_length_unit(v.cast<std::string>());
  c.units_warning = units_warning(mesh, p.units, "V", "units=");
  num("radius", p.radius);
  integer("rings", p.rings);
  if (p.radius <= 0 && p.rings <= 0) throw InputError("give radius (mm) or rings (a count) > 0");
  if (p.radius > 0 && p.rings > 0) throw InputError("give radius or rings, not both");
  if (const py::object v = get("method"); !v.is_none()) c.method = v.cast<std::string>();
  p.method = parse_correction_method(c.method);
  if (const py::object v = get("boundary"); !v.is_none()) p.boundary = parse_region_boundary(v.cast<std::string>());
  num("g1", p.g1);
  num("g2", p.g2);
  if (const py::object v = get("laplacian"); !v.is_none()) p.laplacian = parse_laplacian_kind(v.cast<std::string>());
  if (const py::object v = get("stiffness"); !v.is_none())
    p.stiffness = vector_arg(v, "stiffness", mesh.num_vertices());
  if (const py::object v = get("dynamic"); !v.is_none()) p.dynamic = v.cast<bool>();
  integer("steps", p.steps);
  // A number for the whole region, or an (n,) array: one value per vertex.
  auto tissue = [&](const char* key, double& scalar, Eigen::VectorXd& field) {
    const py::object v = get(key);
    if (v.is_none()) return;
    if (py::isinstance<py::float_>(v) || py::isinstance<py::int_>(v))
      scalar = v.cast<double>();
    else
      field = vector_arg(v, key, mesh.num_vertices());
  };
  tissue("mass", p.tissue.mass, p.tissue.mass_field);
  tissue("elasticity", p.tissue.elasticity, p.tissue.elasticity_field);
  tissue("viscosity", p.tissue.viscosity, p.tissue.viscosity_field);
  // Tissue brushes, "[PROPERTY:]V:RADIUS:VALUE" as `meshpde correct --brush` takes them,
  // painted in order over the fields above.
  if (const py::object v = get("brushes"); !v.is_none()) {
    if (py::isinstance<py::str>(v) || !py::isinstance<py::sequence>(v))
      throw InputError("brushes: expected a list of '[PROPERTY:]V:RADIUS:VALUE' strings");
    for (const py::handle b : py::reinterpret_borrow<py::sequence>(v)) {
      if (!py::isinstance<py::str>(b))
        throw InputError("brushes: expected a list of '[PROPERTY:]V:RADIUS:VALUE' strings");
      with_warnings([&] {
        paint_tissue(mesh, p, b.cast<std::string>(), millimetres_per(p.units));
        return 0;
      });
    }
  }
  if (const py::object v = get("caps"); !v.is_none()) c.caps.rule = v.cast<std::string>();
  Eigen::VectorXi labels;
  if (const py::object v = get("face_labels"); !v.is_none()) {
    const Eigen::VectorXd x = vector_arg(v, "face_labels", mesh.num_faces());
    if (!(x.array() == x.array().round()).all()) throw InputError("face_labels: expected whole numbers");
    labels = x.cast<int>();
  }
  c.caps.caps = find_caps(mesh, labels, parse_cap_rule(c.caps.rule));
  p.held = cap_vertices(c.caps.caps);
  if (const py::object v = get("allow_intersections"); !v.is_none()) p.prevent_intersections = !v.cast<bool>();
  integer("max_substeps", p.max_substeps);
  if (const py::object v = get("solver"); !v.is_none()) {
    c.solver = v.cast<std::string>();
    p.solver = solver_arg(c.solver);
  }
  num("tolerance", p.cg.tolerance);
  check_tolerance(p.cg.tolerance);
  if (const py::object image = get("image"); !image.is_none()) {
    double sigma = kEdgeSigmaMm;
    num("image_sigma", sigma);
    const std::string space = get("space").is_none() ? "lps" : get("space").cast<std::string>();
    p.image.space = parse_space(space);
    num("image_weight", p.image.weight);
    num("search_radius", p.image.search_radius);
    integer("cube", p.image.cube_size);
    integer("passes", p.image.passes);
    Volume volume = volume_arg(image);
    py::gil_scoped_release release;
    p.image.edges = edge_map(volume, sigma);
  }
  return c;
}

// A correction's result: its arrays, and its report (correction_report_json, the
// object `meshpde correct --json` prints) as a dict whose keys are also attributes.
struct PyCorrectionResult {
  CorrectionResult r;
  py::dict report;

  py::object get(const char* key) const { return report[key]; }
  py::dict to_dict() const { return py::dict(report); }
};

// V, F: the surface the handles were given on.
PyCorrectionResult wrap(const Positions& V, const Triangles& F, CorrectionResult r, const CorrectionOptions& c) {
  PyCorrectionResult out{std::move(r), {}};
  out.report = json_to_python(correction_report_json(V, F, c.params, out.r, c.caps));
  if (out.r.applied_fraction < 1)
    PyErr_WarnEx(PyExc_UserWarning,
                 fmt::format("only {:.3f} of the displacement was applied: the whole of it would make the surface "
                             "intersect itself ({})",
                             out.r.applied_fraction, out.r.intersection_action)
                     .c_str(),
                 1);
  if (!c.units_warning.empty()) PyErr_WarnEx(PyExc_UserWarning, c.units_warning.c_str(), 1);
  if (!out.r.region_warning.empty()) PyErr_WarnEx(PyExc_UserWarning, out.r.region_warning.c_str(), 1);
  if (!out.r.handle_warning.empty()) PyErr_WarnEx(PyExc_UserWarning, out.r.handle_warning.c_str(), 1);
  if (!out.r.accuracy_warning.empty()) PyErr_WarnEx(PyExc_RuntimeWarning, out.r.accuracy_warning.c_str(), 1);
  return out;
}

// CorrectionSession with the mesh it owns.
class PyCorrectionSession {
 public:
  PyCorrectionSession(const ArrayLike& V, const ArrayLike& F) : session_(mesh_arg(V, F)) {}
  PyCorrectionResult apply(const py::handle& vertices, const py::handle& moves, const py::dict& options) {
    const CorrectionOptions c = correction_options(session_.mesh(), vertices, moves, options);
    const Positions before = session_.mesh().positions();
    CorrectionResult r;
    {
      py::gil_scoped_release release;
      r = session_.apply(c.params);
    }
    if (!r.converged) throw SolverError("the correction's solve did not converge: " + r.solver_message);
    return wrap(before, session_.mesh().triangles(), std::move(r), c);
  }
  CorrectionSession session_;
};

}  // namespace

void bind_apps(py::module_& m) {
  m.def(
      "_heat",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& sources, const ArrayLike& flux, double dt, int steps,
         double diffusivity, const ArrayLike& initial, bool local, const std::string& laplacian,
         const py::object& callback) {
        return run_propagation(Propagation::Heat, V, F, sources, flux, py::none(), dt, steps, diffusivity, 1.0, 0.0,
                               initial, py::none(), local, laplacian, callback);
      },
      py::arg("V"), py::arg("F"), py::arg("sources"), py::arg("flux"), py::arg("dt"), py::arg("steps"),
      py::arg("diffusivity"), py::arg("initial"), py::arg("local"), py::arg("laplacian"), py::arg("callback"));
  m.def(
      "_wave",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& sources, const ArrayLike& flux,
         const ArrayLike& impulses, double dt, int steps, double speed, double damping, const ArrayLike& initial,
         const ArrayLike& initial_velocity, bool local, const std::string& laplacian, const py::object& callback) {
        return run_propagation(Propagation::Wave, V, F, sources, flux, impulses, dt, steps, 1.0, speed, damping,
                               initial, initial_velocity, local, laplacian, callback);
      },
      py::arg("V"), py::arg("F"), py::arg("sources"), py::arg("flux"), py::arg("impulses"), py::arg("dt"),
      py::arg("steps"), py::arg("speed"), py::arg("damping"), py::arg("initial"), py::arg("initial_velocity"),
      py::arg("local"), py::arg("laplacian"), py::arg("callback"));
  m.def(
      "wave_energy",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& u, const ArrayLike& ut, double speed) {
        const Mesh mesh = mesh_arg(V, F);
        const FemOperators ops = build_cotan_operators(mesh);
        return wave_energy(mesh, ops, vector_arg(u, "u", mesh.num_vertices()),
                           vector_arg(ut, "ut", mesh.num_vertices()), speed);
      },
      py::arg("V"), py::arg("F"), py::arg("u"), py::arg("ut"), py::arg("speed") = 1.0);

  m.def(
      "_fair",
      [](const ArrayLike& V, const ArrayLike& F, const py::handle& fixed, int order, bool regularize, double dt,
         int steps, double damping, const std::string& solver, const std::string& laplacian, double tolerance) {
        check_tolerance(tolerance);
        const Mesh mesh = mesh_arg(V, F);
        const std::vector<int> held = selection_arg(mesh, fixed, "fixed");
        FairParams p;
        p.order = order;
        p.regularize = regularize;
        p.dt = dt;
        p.steps = steps;
        p.damping = damping;
        p.cg.tolerance = tolerance;
        p.solver = solver_arg(solver);
        p.laplacian = parse_laplacian_kind(laplacian);
        FairResult r;
        {
          py::gil_scoped_release release;
          r = fair(mesh, held, p);
        }
        if (!r.converged) throw SolverError("fairing did not converge: " + r.message);
        auto quality = [](const TriangleQuality& q) {
          py::dict d;
          d["min_angle_deg"] = q.min_angle_deg;
          d["area_ratio"] = q.area_ratio;
          d["area_histogram"] = q.area_histogram;
          return d;
        };
        py::dict d;
        d["V"] = to_numpy(Eigen::MatrixXd(r.V));
        d["before"] = quality(r.before);
        d["after"] = quality(r.after);
        d["cg_iterations"] = r.cg_iterations;
        d["worst_residual"] = r.worst_residual;
        d["solver"] = to_string(r.solver);
        d["laplacian"] = to_string(r.laplacian);
        d["laplacian_reason"] = r.laplacian_reason;
        return py::module_::import("types").attr("SimpleNamespace")(**d);
      },
      py::arg("V"), py::arg("F"), py::arg("fixed"), py::arg("order"), py::arg("regularize"), py::arg("dt"),
      py::arg("steps"), py::arg("damping"), py::arg("solver"), py::arg("laplacian"),
      py::arg("tolerance") = FairParams{}.cg.tolerance);

  m.def(
      "_interpolate",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& vertices, const ArrayLike& values,
         const std::string& kind, const std::string& method, double g1, double g2, const std::string& solver,
         const std::string& laplacian, double tolerance) {
        check_tolerance(tolerance);
        const Mesh mesh = mesh_arg(V, F);
        const std::vector<int> at = vertices_arg(vertices, "vertices", mesh.num_vertices());
        const FieldKind k = field_kind_arg(kind);
        const Field x =
            field_arg(values, "values", static_cast<Eigen::Index>(at.size()), k == FieldKind::Scalar ? 1 : 3);
        if (method != "componentwise" && method != "connection")
          throw InputError(fmt::format("method: expected 'componentwise' or 'connection', got '{}'", method));
        std::vector<InterpolationConstraint> cons;
        for (std::size_t c = 0; c < at.size(); ++c)
          cons.push_back({at[c], x.row(static_cast<Eigen::Index>(c)).transpose()});
        InterpolationParams p;
        p.g1 = g1;
        p.g2 = g2;
        p.method = method == "connection" ? TangentMethod::Connection : TangentMethod::Componentwise;
        p.solver = solver_arg(solver);
        p.cg.tolerance = tolerance;
        p.laplacian = parse_laplacian_kind(laplacian);
        InterpolationResult r;
        {
          py::gil_scoped_release release;
          r = interpolate(mesh, k, cons, p);
        }
        if (!r.cg.converged()) throw SolverError("interpolation did not converge: " + r.cg.message);
        if (k == FieldKind::Scalar) return py::object(to_numpy(Eigen::VectorXd(r.values.col(0))));
        return py::object(to_numpy(r.values));
      },
      py::arg("V"), py::arg("F"), py::arg("vertices"), py::arg("values"), py::arg("kind"), py::arg("method"),
      py::arg("g1"), py::arg("g2"), py::arg("solver"), py::arg("laplacian"),
      py::arg("tolerance") = InterpolationParams{}.cg.tolerance);

  py::class_<InterpolationSolver>(m, "InterpolationSolver",
                                  R"doc(InterpolationSolver(V, F, kind="scalar", g1=0, g2=1, laplacian="auto")

Scattered-data interpolation that keeps its factor between solves, for values set,
changed and removed one at a time (painting). set_value(vertex, value) adds a constraint
or changes its value, remove(vertex) frees it, solve() returns the field: (n,) for
scalars, (n, 3) for displacements and tangent vectors (componentwise, projected). New
values at the same vertices cost one solve with the kept factor; added or removed
vertices a small Schur complement against it (factored afresh after max_changes of
them, in the last factor's order when the free set changed by at most 5 %:
reused_orders counts those). With g1 = 0 and at most laplacian_factor_up_to (64) constraints at a
fresh start the factor is the Laplacian's, applied twice per solve (laplacian_factor: True), else
the whole operator's. Answers equal interpolate(..., solver="direct") to rounding.)doc")
      .def(py::init([](const ArrayLike& V, const ArrayLike& F, const std::string& kind, double g1, double g2,
                       const std::string& laplacian) {
             const FieldKind k = field_kind_arg(kind);
             InterpolationParams p;
             p.g1 = g1;
             p.g2 = g2;
             p.laplacian = parse_laplacian_kind(laplacian);
             const Mesh mesh = mesh_arg(V, F);
             py::gil_scoped_release release;
             return std::make_unique<InterpolationSolver>(mesh, k, p);  // builds and owns its operators
           }),
           py::arg("V"), py::arg("F"), py::arg("kind") = "scalar", py::arg("g1") = 0.0, py::arg("g2") = 1.0,
           py::arg("laplacian") = "auto")
      .def(
          "set_value",
          [](InterpolationSolver& s, int vertex, const ArrayLike& value) {
            const py::array_t<double> a = py::array_t<double, py::array::forcecast>::ensure(value);
            if (!a) throw InputError("value: expected a number or 3 numbers");
            Eigen::VectorXd x(a.size());
            for (py::ssize_t k = 0; k < a.size(); ++k) x[k] = a.data()[k];
            s.set_value(vertex, x);
          },
          py::arg("vertex"), py::arg("value"))
      .def("remove", &InterpolationSolver::remove, py::arg("vertex"))
      .def("clear", &InterpolationSolver::clear)
      .def("solve",
           [](InterpolationSolver& s) {
             InterpolationResult r;
             {
               py::gil_scoped_release release;
               r = s.solve();
             }
             if (r.values.cols() == 1) return py::object(to_numpy(Eigen::VectorXd(r.values.col(0))));
             return py::object(to_numpy(r.values));
           })
      .def_property_readonly("num_constraints", &InterpolationSolver::num_constraints)
      .def_property_readonly("vertices",
                             [](const InterpolationSolver& s) {
                               std::vector<int> v;
                               for (const auto& c : s.constraints()) v.push_back(c.vertex);
                               return v;
                             })
      .def_property_readonly("factorizations", &InterpolationSolver::factorizations)
      .def_property_readonly("reused_orders", &InterpolationSolver::reused_orders)
      .def_property_readonly("laplacian_factor", &InterpolationSolver::laplacian_factor)
      .def_property_readonly("changed_constraints", &InterpolationSolver::changed_constraints)
      .def_readwrite("max_changes", &InterpolationSolver::max_changes)
      .def_readwrite("laplacian_factor_up_to", &InterpolationSolver::laplacian_factor_up_to);

  py::class_<PyCorrectionResult>(
      m, "CorrectionResult",
      "A correction's report. Its scalar fields carry the names of `meshpde correct --json`'s keys.")
      .def_property_readonly(
          "V", [](const PyCorrectionResult& c) { return to_numpy(Eigen::MatrixXd(c.r.V)); },
          "corrected positions, (n, 3), mesh units")
      .def_property_readonly(
          "displacement", [](const PyCorrectionResult& c) { return to_numpy(c.r.displacement); },
          "displacement per vertex, (n, 3), mesh units")
      .def_property_readonly(
          "region", [](const PyCorrectionResult& c) { return to_numpy(c.r.region); },
          "vertices of the region of influence (handles included)")
      .def_property_readonly("moved_vertices", [](const PyCorrectionResult& c) { return c.r.moved_vertices; })
      .def_property_readonly("max_displacement", [](const PyCorrectionResult& c) { return c.r.max_displacement; })
      .def_property_readonly("region_vertices", [](const PyCorrectionResult& c) { return c.r.region.size(); })
      .def_property_readonly("new_self_intersections",
                             [](const PyCorrectionResult& c) { return c.r.new_self_intersections; })
      .def_property_readonly("time_ms", [](const PyCorrectionResult& c) { return c.r.time_ms; })
      .def_property_readonly("method", [](const PyCorrectionResult& c) { return c.get("method"); })
      .def_property_readonly("boundary", [](const PyCorrectionResult& c) { return c.get("boundary"); })
      .def_property_readonly("dynamic", [](const PyCorrectionResult& c) { return c.get("dynamic"); })
      .def_property_readonly("laplacian",
                             [](const PyCorrectionResult& c) { return std::string(to_string(c.r.laplacian)); })
      .def_property_readonly("laplacian_reason", [](const PyCorrectionResult& c) { return c.r.laplacian_reason; })
      .def_property_readonly("relative_residual", [](const PyCorrectionResult& c) { return c.r.relative_residual; })
      .def_property_readonly("condition_estimate", [](const PyCorrectionResult& c) { return c.r.condition_estimate; })
      .def_property_readonly("error_bound", [](const PyCorrectionResult& c) { return c.r.error_bound; })
      .def_property_readonly("accuracy_warning", [](const PyCorrectionResult& c) { return c.get("accuracy_warning"); })
      .def_property_readonly(
          "region_warning", [](const PyCorrectionResult& c) { return c.get("region_warning"); },
          "set when the region holds only the handles (a radius below one edge): only they move")
      .def_property_readonly(
          "handle_warning", [](const PyCorrectionResult& c) { return c.get("handle_warning"); },
          "set when a handle point was given farther from the surface than the region reaches (another frame or "
          "unit?); names the RAS/LPS mix-up when the point with x and y negated lies on the surface")
      .def_property_readonly("applied_fraction", [](const PyCorrectionResult& c) { return c.r.applied_fraction; })
      .def_property_readonly("substeps", [](const PyCorrectionResult& c) { return c.r.substeps; })
      .def_property_readonly("intersection_action", [](const PyCorrectionResult& c) { return c.r.intersection_action; })
      .def_property_readonly("handles", [](const PyCorrectionResult& c) { return c.get("handles"); })
      .def_property_readonly("solver", [](const PyCorrectionResult& c) { return c.get("solver"); })
      .def_property_readonly(
          "units", [](const PyCorrectionResult& c) { return c.get("units"); },
          "unit of the mesh's coordinates: mm, cm or m")
      .def_property_readonly(
          "image", [](const PyCorrectionResult& c) { return c.report.contains("image") ? c.get("image") : py::none(); })
      .def("to_dict", &PyCorrectionResult::to_dict, "The report as a dict, with the keys of `meshpde correct --json`.")
      .def("__repr__", [](const PyCorrectionResult& c) {
        return fmt::format("<CorrectionResult moved_vertices={} max_displacement={:.4g} new_self_intersections={}>",
                           c.r.moved_vertices, c.r.max_displacement, c.r.new_self_intersections);
      });

  // The library's defaults of a correction's options (CorrectionParams), under the names
  // correct() and CorrectionSession.apply() take: their signatures show the same values,
  // which a test checks against this.
  m.def("_correction_defaults", [] {
    const CorrectionParams d;
    py::dict o;
    o["units"] = to_string(d.units);
    o["radius"] = d.radius;
    o["rings"] = d.rings;
    o["method"] = to_string(d.method);
    o["boundary"] = to_string(d.boundary);
    o["handle_radius"] = d.handle_radius;
    o["g1"] = d.g1;
    o["g2"] = d.g2;
    o["laplacian"] = to_string(d.laplacian);
    o["dynamic"] = d.dynamic;
    o["steps"] = d.steps;
    o["mass"] = d.tissue.mass;
    o["elasticity"] = d.tissue.elasticity;
    o["viscosity"] = d.tissue.viscosity;
    o["allow_intersections"] = !d.prevent_intersections;
    o["max_substeps"] = d.max_substeps;
    o["image_weight"] = d.image.weight;
    o["image_sigma"] = kEdgeSigmaMm;
    o["search_radius"] = d.image.search_radius;
    o["cube"] = d.image.cube_size;
    o["passes"] = d.image.passes;
    o["solver"] = to_string(d.solver);
    o["tolerance"] = d.cg.tolerance;
    o["space"] = std::string(d.image.space == Space::LPS ? "lps" : "ras");
    return o;
  });

  m.def(
      "_correct",
      [](const ArrayLike& V, const ArrayLike& F, const ArrayLike& vertices, const py::handle& moves,
         const py::dict& options) {
        const Mesh mesh = mesh_arg(V, F);
        const CorrectionOptions c = correction_options(mesh, vertices, moves, options);
        CorrectionResult r;
        {
          py::gil_scoped_release release;
          r = correct_vessel(mesh, c.params);
        }
        if (!r.converged) throw SolverError("the correction's solve did not converge: " + r.solver_message);
        return wrap(mesh.positions(), mesh.triangles(), std::move(r), c);
      },
      py::arg("V"), py::arg("F"), py::arg("vertices"), py::arg("moves"), py::arg("options"));

  py::class_<PyCorrectionSession>(m, "_CorrectionSession")
      .def(py::init<const ArrayLike&, const ArrayLike&>(), py::arg("V"), py::arg("F"))
      .def("_apply", &PyCorrectionSession::apply, py::arg("vertices"), py::arg("moves"), py::arg("options"))
      .def(
          "undo", [](PyCorrectionSession& s) { s.session_.undo(); }, "Goes back one correction.")
      .def(
          "redo", [](PyCorrectionSession& s) { s.session_.redo(); }, "Re-applies the correction undone last.")
      .def_property_readonly("can_undo", [](const PyCorrectionSession& s) { return s.session_.can_undo(); })
      .def_property_readonly("can_redo", [](const PyCorrectionSession& s) { return s.session_.can_redo(); })
      .def_property_readonly(
          "V", [](const PyCorrectionSession& s) { return to_numpy(Eigen::MatrixXd(s.session_.mesh().positions())); },
          "current positions, (n, 3)")
      .def_property_readonly(
          "original", [](const PyCorrectionSession& s) { return to_numpy(Eigen::MatrixXd(s.session_.original())); },
          "positions before the first correction, (n, 3)")
      .def_property_readonly("F", [](const PyCorrectionSession& s) { return to_numpy(s.session_.mesh().triangles()); })
      .def(
          "new_self_intersections", [](const PyCorrectionSession& s) { return s.session_.new_self_intersections(); },
          "Triangle pairs intersecting now that did not in the original.");
}

}  // namespace meshpde::python
