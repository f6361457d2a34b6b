#include "meshpde/distributed/distributed_solve.h"

#include <fmt/format.h>
#include <petscksp.h>
#include <sys/resource.h>

#include <chrono>
#include <unordered_map>

#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"
#include "meshpde/operators/fem_operators.h"
#include "petsc_check.h"

namespace meshpde {

namespace {

constexpr auto check = detail::petsc_check;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The PETSc objects of one solve, destroyed together whatever happens.
struct Objects {
  Mat K = nullptr, Kc = nullptr, A = nullptr;
  Vec D = nullptr, Mv = nullptr, mask = nullptr, x = nullptr, b = nullptr, uc = nullptr;
  Vec t1 = nullptr, t2 = nullptr, t3 = nullptr;
  PC inner = nullptr;
  KSP ksp = nullptr;
  double g1 = 0, g2 = 1;
  ~Objects() {
    KSPDestroy(&ksp);
    PCDestroy(&inner);
    for (Vec* v : {&D, &Mv, &mask, &x, &b, &uc, &t1, &t2, &t3}) VecDestroy(v);
    for (Mat* m : {&K, &Kc, &A}) MatDestroy(m);
  }
};

// y = (g1 K + g2 K D K) x, unprojected.
PetscErrorCode apply_operator(Objects& o, Vec x, Vec y) {
  PetscCall(MatMult(o.K, x, o.t1));  // t1 = K x
  if (o.g2 != 0) {
    PetscCall(VecPointwiseMult(o.t2, o.D, o.t1));  // t2 = D K x
    PetscCall(MatMult(o.K, o.t2, y));              // y = K D K x
    PetscCall(VecScale(y, o.g2));
    if (o.g1 != 0) PetscCall(VecAXPY(y, o.g1, o.t1));
  } else {
    PetscCall(VecCopy(o.t1, y));
    PetscCall(VecScale(y, o.g1));
  }
  return 0;
}

// The constrained operator P A P + (I - P), P the free vertices' mask: SPD, and its
// constrained rows give x_c = b_c = 0.
PetscErrorCode shell_mult(Mat A, Vec x, Vec y) {
  Objects* o = nullptr;
  PetscCall(MatShellGetContext(A, &o));
  PetscCall(VecPointwiseMult(o->t3, o->mask, x));
  PetscCall(apply_operator(*o, o->t3, y));
  PetscCall(VecPointwiseMult(y, o->mask, y));
  PetscCall(VecAXPY(y, 1.0, x));
  PetscCall(VecAXPY(y, -1.0, o->t3));  // + (I - P) x
  return 0;
}

// z = P K_c^-1 M K_c^-1 P r / g2 + (I - P) r (or K_c^-1 / g1 for a pure membrane):
// K D K's inverse with D = M^-1, each K^-1 one AMG cycle on K_c.
PetscErrorCode shell_precondition(PC pc, Vec r, Vec z) {
  Objects* o = nullptr;
  PetscCall(PCShellGetContext(pc, &o));
  PetscCall(VecPointwiseMult(o->t3, o->mask, r));
  PetscCall(PCApply(o->inner, o->t3, o->t1));
  if (o->g2 != 0) {
    PetscCall(VecPointwiseMult(o->t2, o->Mv, o->t1));  // M t1
    PetscCall(VecPointwiseMult(o->t2, o->mask, o->t2));
    PetscCall(PCApply(o->inner, o->t2, z));
    PetscCall(VecScale(z, 1.0 / o->g2));
  } else {
    PetscCall(VecCopy(o->t1, z));
    PetscCall(VecScale(z, 1.0 / o->g1));
  }
  PetscCall(VecPointwiseMult(z, o->mask, z));
  PetscCall(VecAXPY(z, 1.0, r));
  PetscCall(VecAXPY(z, -1.0, o->t3));
  return 0;
}

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

}  // namespace

PetscScope::PetscScope(int* argc, char*** argv) {
  PetscBool up = PETSC_FALSE;
  check(PetscInitialized(&up), "PetscInitialized");
  if (!up) {
    check(PetscInitialize(argc, argv, nullptr, nullptr), "PetscInitialize");
    started_ = true;
  }
}

PetscScope::~PetscScope() {
  if (started_) PetscFinalize();
}

namespace {

// The steady solve (g1 K + g2 K D K) u = 0 on the free vertices, u held at the owned
// vertices `held` marks (held_values: one row an owned vertex, one column a component;
// the same constraint set for every component, so one K_c and one AMG serve them all).
DistributedResult solve_held(const MeshPart& part, const std::vector<char>& held, const Eigen::MatrixXd& held_values,
                             const DistributedSolveParams& p, MPI_Comm comm) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(p.g1 >= 0) || !(p.g2 >= 0) || p.g1 + p.g2 == 0)
    throw InputError(fmt::format("g1 and g2 must be >= 0 and not both 0 (got {} and {})", p.g1, p.g2));
  const PetscInt n = static_cast<PetscInt>(part.global_vertices), nl = part.owned;
  const Mesh& mesh = part.mesh;
  // The local operators: rows of the owned vertices are whole (the part holds every
  // triangle around them); the ghosts' rows are not used.
  const FemOperators ops = build_cotan_operators(mesh);
  Objects o;
  o.g1 = p.g1;
  o.g2 = p.g2;
  {
    std::vector<PetscInt> d_nnz(static_cast<std::size_t>(nl)), o_nnz(static_cast<std::size_t>(nl));
    const auto off = mesh.offsets();
    const auto nbr = mesh.neighbors();
    for (int i = 0; i < nl; ++i) {
      d_nnz[i] = 1;
      o_nnz[i] = 0;
      for (int q = off[i]; q < off[i + 1]; ++q) (nbr[q] < nl ? d_nnz[i] : o_nnz[i])++;
    }
    check(MatCreateAIJ(comm, nl, nl, n, n, 0, d_nnz.data(), 0, o_nnz.data(), &o.K), "MatCreateAIJ");
    std::vector<PetscInt> cols;
    std::vector<PetscScalar> vals;
    for (int i = 0; i < nl; ++i) {
      cols.assign(1, static_cast<PetscInt>(part.global_id[i]));
      vals.assign(1, ops.Kii[i]);
      for (int q = off[i]; q < off[i + 1]; ++q) {
        cols.push_back(static_cast<PetscInt>(part.global_id[nbr[q]]));
        vals.push_back(ops.Kij[q]);
      }
      const PetscInt row = static_cast<PetscInt>(part.global_id[i]);
      check(MatSetValues(o.K, 1, &row, static_cast<PetscInt>(cols.size()), cols.data(), vals.data(), INSERT_VALUES),
            "MatSetValues");
    }
    check(MatAssemblyBegin(o.K, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin");
    check(MatAssemblyEnd(o.K, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd");
  }
  check(MatCreateVecs(o.K, &o.x, &o.b), "MatCreateVecs");
  for (Vec* v : {&o.D, &o.Mv, &o.mask, &o.uc, &o.t1, &o.t2, &o.t3}) check(VecDuplicate(o.x, v), "VecDuplicate");
  // D, the mask and the held values, each process setting its own entries.
  std::vector<PetscInt> held_rows;  // global rows of the constrained vertices this process owns
  {
    PetscScalar *d = nullptr, *mv = nullptr, *m = nullptr;
    check(VecGetArray(o.D, &d), "VecGetArray");
    check(VecGetArray(o.Mv, &mv), "VecGetArray");
    check(VecGetArray(o.mask, &m), "VecGetArray");
    for (int i = 0; i < nl; ++i) {
      d[i] = ops.D(i);
      mv[i] = ops.mass[i];
      m[i] = held[static_cast<std::size_t>(i)] ? 0.0 : 1.0;
      if (held[static_cast<std::size_t>(i)]) held_rows.push_back(static_cast<PetscInt>(part.global_id[i]));
    }
    VecRestoreArray(o.D, &d);
    VecRestoreArray(o.Mv, &mv);
    VecRestoreArray(o.mask, &m);
  }
  // K_c and its AMG.
  check(MatDuplicate(o.K, MAT_COPY_VALUES, &o.Kc), "MatDuplicate");
  check(MatZeroRowsColumns(o.Kc, static_cast<PetscInt>(held_rows.size()), held_rows.data(), 1.0, nullptr, nullptr),
        "MatZeroRowsColumns");
  DistributedResult r;
  check(PCCreate(comm, &o.inner), "PCCreate");
  check(PCSetOperators(o.inner, o.Kc, o.Kc), "PCSetOperators");
#if defined(PETSC_HAVE_HYPRE)
  check(PCSetType(o.inner, PCHYPRE), "PCSetType(hypre)");
  check(PCHYPRESetType(o.inner, "boomeramg"), "PCHYPRESetType");
#else
  check(PCSetType(o.inner, PCGAMG), "PCSetType(gamg)");
#endif
  // Options of the inner AMG under the prefix meshpde_amg_ (-meshpde_amg_pc_hypre_...),
  // after the defaults set here. BoomerAMG's defaults measured best on a 655k sphere
  // (37 CG iterations; HMIS/PMIS with ext+i took 78-145, GAMG thousands).
  check(PCSetOptionsPrefix(o.inner, "meshpde_amg_"), "PCSetOptionsPrefix");
  check(PCSetFromOptions(o.inner), "PCSetFromOptions");
  {
    PCType type = nullptr;
    check(PCGetType(o.inner, &type), "PCGetType");
    r.preconditioner = std::string(type) == PCHYPRE ? "hypre-boomeramg" : type;
  }
  check(PCSetUp(o.inner), "PCSetUp");
  check(MatCreateShell(comm, nl, nl, n, n, &o, &o.A), "MatCreateShell");
  check(MatShellSetOperation(o.A, MATOP_MULT, reinterpret_cast<void (*)(void)>(shell_mult)), "MatShellSetOperation");
  check(KSPCreate(comm, &o.ksp), "KSPCreate");
  check(KSPSetOperators(o.ksp, o.A, o.A), "KSPSetOperators");
  check(KSPSetType(o.ksp, KSPCG), "KSPSetType");
  PC pc = nullptr;
  check(KSPGetPC(o.ksp, &pc), "KSPGetPC");
  check(PCSetType(pc, PCSHELL), "PCSetType(shell)");
  check(PCShellSetContext(pc, &o), "PCShellSetContext");
  check(PCShellSetApply(pc, shell_precondition), "PCShellSetApply");
  check(KSPSetTolerances(o.ksp, p.tolerance, 0.0, PETSC_DEFAULT, p.max_iterations), "KSPSetTolerances");
  check(KSPSetFromOptions(o.ksp), "KSPSetFromOptions");
  r.rank.setup_seconds = seconds_since(t0);
  const auto t1 = std::chrono::steady_clock::now();
  r.values.resize(nl, held_values.cols());
  for (Eigen::Index c = 0; c < held_values.cols(); ++c) {
    // b = -P A u_c (zero on the constrained rows), u_c the held values of component c.
    PetscScalar* u = nullptr;
    check(VecGetArray(o.uc, &u), "VecGetArray");
    for (int i = 0; i < nl; ++i) u[i] = held[static_cast<std::size_t>(i)] ? held_values(i, c) : 0.0;
    VecRestoreArray(o.uc, &u);
    check(apply_operator(o, o.uc, o.b), "the operator's apply");
    check(VecPointwiseMult(o.b, o.mask, o.b), "VecPointwiseMult");
    check(VecScale(o.b, -1.0), "VecScale");
    check(VecZeroEntries(o.x), "VecZeroEntries");
    check(KSPSolve(o.ksp, o.b, o.x), "KSPSolve");
    KSPConvergedReason reason;
    PetscInt its = 0;
    check(KSPGetConvergedReason(o.ksp, &reason), "KSPGetConvergedReason");
    check(KSPGetIterationNumber(o.ksp, &its), "KSPGetIterationNumber");
    r.iterations = std::max(r.iterations, static_cast<int>(its));
    // The true residual of the constrained system.
    PetscReal bn = 0, rn = 0;
    check(MatMult(o.A, o.x, o.t1), "MatMult");
    check(VecAYPX(o.t1, -1.0, o.b), "VecAYPX");
    check(VecNorm(o.t1, NORM_2, &rn), "VecNorm");
    check(VecNorm(o.b, NORM_2, &bn), "VecNorm");
    const double residual = bn > 0 ? static_cast<double>(rn / bn) : static_cast<double>(rn);
    r.relative_residual = std::max(r.relative_residual, residual);
    if (reason < 0)
      throw SolverError(
          fmt::format("distributed CG did not converge: {} after {} iterations (relative residual {:.3g})",
                      KSPConvergedReasons[reason], its, residual));
    check(VecAXPY(o.x, 1.0, o.uc), "VecAXPY");  // u = u_free + u_held
    const PetscScalar* xs = nullptr;
    check(VecGetArrayRead(o.x, &xs), "VecGetArrayRead");
    r.values.col(c) = Eigen::Map<const Eigen::VectorXd>(xs, nl);
    VecRestoreArrayRead(o.x, &xs);
  }
  r.rank.solve_seconds = seconds_since(t1);
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  r.rank.rank = rank;
  r.rank.owned = nl;
  r.rank.ghosts = mesh.num_vertices() - nl;
  r.rank.ghost_fraction = nl ? static_cast<double>(r.rank.ghosts) / nl : 0.0;
  r.rank.peak_rss_mb = peak_rss_mb();
  return r;
}

}  // namespace

DistributedResult distributed_interpolate(const MeshPart& part, const std::vector<InterpolationConstraint>& constraints,
                                          const DistributedSolveParams& p, MPI_Comm comm) {
  if (constraints.empty()) throw InputError("no constraint: give at least one vertex and value");
  // Every process has the same list: these checks throw on all of them alike.
  std::unordered_map<int, int> seen;
  for (std::size_t k = 0; k < constraints.size(); ++k) {
    const int v = constraints[k].vertex;
    if (v < 0 || v >= part.global_vertices)
      throw InputError(fmt::format("constraint {}: vertex {} does not exist (the mesh has {} vertices)", k + 1, v,
                                   part.global_vertices));
    if (constraints[k].value.size() != 1)
      throw InputError(fmt::format("constraint {}: one value expected (scalar interpolation)", k + 1));
    if (!seen.emplace(v, static_cast<int>(k)).second)
      throw InputError(fmt::format("constraints {} and {} both hold vertex {}", seen[v] + 1, k + 1, v));
  }
  std::unordered_map<long long, int> owned_local;  // original id -> local index, owned vertices
  for (int i = 0; i < part.owned; ++i) owned_local.emplace(part.original_id[i], i);
  std::vector<char> held(static_cast<std::size_t>(part.owned), 0);
  Eigen::MatrixXd values = Eigen::MatrixXd::Zero(part.owned, 1);
  for (const auto& c : constraints)
    if (const auto it = owned_local.find(c.vertex); it != owned_local.end()) {
      held[static_cast<std::size_t>(it->second)] = 1;
      values(it->second, 0) = c.value[0];
    }
  return solve_held(part, held, values, p, comm);
}

DistributedResult distributed_fair(const MeshPart& part, const std::vector<std::string>& fixed, int order,
                                   const DistributedSolveParams& params, MPI_Comm comm) {
  if (order != 1 && order != 2) throw InputError(fmt::format("fairing order must be 1 or 2, got {}", order));
  if (fixed.empty()) throw InputError("give the fixed vertices: boundary, halfspace:NX,NY,NZ:D or all");
  for (const auto& spec : fixed)
    if (spec != "boundary" && spec != "all" && spec.rfind("halfspace:", 0) != 0)
      throw InputError(
          fmt::format("fixed vertices '{}': a distributed run takes boundary, halfspace:NX,NY,NZ:D or all (the "
                      "others name vertices or distances that need the whole mesh)",
                      spec));
  // Boundary edges of an owned vertex are whole in its part (it holds every triangle
  // around the vertex), so the local selection is right for the owned vertices.
  std::vector<char> held(static_cast<std::size_t>(part.owned), 0);
  for (const int v : select_vertices(part.mesh, fixed))
    if (v < part.owned) held[static_cast<std::size_t>(v)] = 1;
  const Eigen::MatrixXd X = part.mesh.positions().topRows(part.owned);
  DistributedSolveParams p = params;
  p.g1 = order == 1 ? 1.0 : 0.0;
  p.g2 = order == 2 ? 1.0 : 0.0;
  return solve_held(part, held, X, p, comm);
}

}  // namespace meshpde
