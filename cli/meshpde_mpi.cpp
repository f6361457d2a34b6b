// meshpde-mpi: distributed solves over MPI (target meshpde::distributed).
//   meshpde partition MESH --parts N -o DIR        (runs meshpde-mpi partition: one process)
//   mpirun -n N meshpde-mpi interpolate DIR --constraints FILE -o OUTDIR [--json]
//   mpirun -n N meshpde-mpi fair DIR --fixed boundary|halfspace:NX,NY,NZ:D|all --order 1|2 -o OUTDIR [--json]
//   meshpde-mpi join DIR OUTDIR -o MESH           (one process: the results as one mesh)
// Every process reads only its own part (DIR/part-RANK.ply). Exit codes as meshpde's:
// 0 success, 1 bad input or failed solve (on every rank: a part one rank cannot read
// stops them all), 2 usage error.
#include <fmt/format.h>
#include <mpi.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <filesystem>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>

#include "meshpde/core/errors.h"
#include "meshpde/distributed/distributed_solve.h"
#include "meshpde/distributed/partition.h"
#include "meshpde/io/mesh_io.h"
#include "usage.h"

namespace {

using namespace meshpde;

// True on every rank when any rank says true.
bool any_rank(bool mine, MPI_Comm comm) {
  int in = mine ? 1 : 0, out = 0;
  MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_MAX, comm);
  return out != 0;
}

// Every rank's error message (empty: none) gathered on rank 0, which prints each
// distinct one once with the ranks that gave it ("ranks 0-3, 7: ..."): a mistake every
// rank makes alike (a constraint on a vertex the mesh lacks) is one line, not one a rank.
void report_errors(const std::string& mine, MPI_Comm comm) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const int length = static_cast<int>(mine.size());
  std::vector<int> lengths(static_cast<std::size_t>(size)), offsets(static_cast<std::size_t>(size), 0);
  MPI_Gather(&length, 1, MPI_INT, lengths.data(), 1, MPI_INT, 0, comm);
  std::string all;
  if (rank == 0) {
    for (int k = 1; k < size; ++k) offsets[k] = offsets[k - 1] + lengths[k - 1];
    all.resize(static_cast<std::size_t>(offsets.back() + lengths.back()));
  }
  MPI_Gatherv(mine.data(), length, MPI_CHAR, all.data(), lengths.data(), offsets.data(), MPI_CHAR, 0, comm);
  if (rank != 0) return;
  std::vector<std::pair<std::string, std::vector<int>>> distinct;  // in order of the first rank
  for (int k = 0; k < size; ++k) {
    if (lengths[k] == 0) continue;
    std::string text = all.substr(static_cast<std::size_t>(offsets[k]), static_cast<std::size_t>(lengths[k]));
    auto it = std::find_if(distinct.begin(), distinct.end(), [&](const auto& d) { return d.first == text; });
    if (it == distinct.end()) {
      distinct.emplace_back(std::move(text), std::vector<int>{k});
    } else {
      it->second.push_back(k);
    }
  }
  for (const auto& [text, ranks] : distinct) {
    std::string who;
    for (std::size_t i = 0; i < ranks.size();) {
      std::size_t j = i;
      while (j + 1 < ranks.size() && ranks[j + 1] == ranks[j] + 1) ++j;
      who += fmt::format("{}{}", who.empty() ? "" : ", ",
                         j == i ? fmt::format("{}", ranks[i]) : fmt::format("{}-{}", ranks[i], ranks[j]));
      i = j + 1;
    }
    fmt::print(stderr, "meshpde-mpi: error: {} {}: {}\n", ranks.size() == 1 ? "rank" : "ranks", who, text);
  }
}

struct Args {
  std::string command, dir, constraints, out, mesh, results, laplacian = "cotan";
  std::vector<std::string> fixed;
  int order = 2, parts = 0;
  double g1 = 0, g2 = 1, rtol = 1e-12;
  int max_iterations = 5000;
  bool json = false;
};

// meshpde partition MESH --parts N -o DIR: one process reads the whole mesh.
int run_partition(const Args& a) {
  MeshData d = read_mesh(a.mesh);
  for (const auto& w : d.warnings) fmt::print(stderr, "warning: {}\n", w);
  Mesh mesh;
  try {
    mesh = Mesh(d.V, d.F);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", a.mesh, e.what()));
  }
  const std::vector<int> part_of = partition_vertices(mesh, a.parts);
  const PartitionSummary s = write_partition(d, part_of, a.out, a.mesh);
  int most = 0, ghosts = 0;
  for (int k = 0; k < s.parts; ++k) {
    most = std::max(most, s.owned[k]);
    ghosts += s.ghosts[k];
  }
  const double imbalance = most * s.parts / static_cast<double>(mesh.num_vertices());
  if (a.json) {
    std::cout << nlohmann::json{{"parts", s.parts},
                                {"vertices", mesh.num_vertices()},
                                {"owned", s.owned},
                                {"ghosts", s.ghosts},
                                {"part_faces", s.faces},
                                {"cut_edges", s.cut_edges},
                                {"imbalance", imbalance},
                                {"ghost_fraction", static_cast<double>(ghosts) / mesh.num_vertices()},
                                {"output", a.out}}
                     .dump(2)
              << std::endl;
  } else {
    fmt::print("{}: {} parts of {} vertices ({} to {} each, imbalance {:.3f}), {} cut edges, {} ghosts in all\n", a.out,
               s.parts, mesh.num_vertices(), *std::min_element(s.owned.begin(), s.owned.end()), most, imbalance,
               s.cut_edges, ghosts);
  }
  return 0;
}

// A vertex given by its index in the input mesh of n vertices: what a distributed run
// takes for a vertex (no @X,Y,Z, no process holds the whole mesh).
std::function<int(const std::string&)> vertex_index(long long n) {
  return [n](const std::string& spec) {
    int v = -1;
    const auto [end, ec] = std::from_chars(spec.data(), spec.data() + spec.size(), v);
    if (ec != std::errc() || end != spec.data() + spec.size())
      throw InputError(
          fmt::format("vertex \"{}\": a distributed run takes vertex indices of the input mesh "
                      "(no @X,Y,Z: no process holds the whole mesh)",
                      spec));
    if (v < 0 || v >= n) throw InputError(fmt::format("vertex {} does not exist (the mesh has {} vertices)", v, n));
    return v;
  };
}

// meshpde-mpi join DIR RESULTS -o MESH: the parts and the ranks' result files as one
// mesh (one process): interpolate's u-RANK.csv becomes the vertex field "u", fair's
// positions-RANK.csv the vertex positions.
int run_join(const Args& a) {
  const std::filesystem::path results(a.results);
  const bool has_u = std::filesystem::exists(results / "u-0.csv");
  const bool has_positions = std::filesystem::exists(results / "positions-0.csv");
  if (has_u == has_positions)
    throw InputError(
        fmt::format("{}: expected the output of one meshpde-mpi run: u-0.csv (interpolate) or "
                    "positions-0.csv (fair), {}",
                    results.string(), has_u ? "found both" : "found neither"));
  const std::string prefix = has_u ? "u" : "positions";
  const int columns = has_u ? 1 : 3;
  const int parts = read_partition_index(a.dir).parts;
  MeshData d = read_partitioned_mesh(a.dir);
  // Each rank's file is the constraints format ("vertex,values", a header allowed):
  // read by its parser, vertices as indices of the input.
  Eigen::MatrixXd values(d.V.rows(), columns);
  std::vector<char> seen(static_cast<std::size_t>(d.V.rows()), 0);
  for (int p = 0; p < parts; ++p) {
    const auto file = results / fmt::format("{}-{}.csv", prefix, p);
    if (!std::filesystem::exists(file))
      throw InputError(
          fmt::format("{}: missing (the partition has {} parts, one result file each)", file.string(), parts));
    for (const auto& c : parse_constraints(vertex_index(d.V.rows()), read_file(file), columns, file.string())) {
      if (seen[static_cast<std::size_t>(c.vertex)]++)
        throw InputError(fmt::format("{}: vertex {} has a value already", file.string(), c.vertex));
      values.row(c.vertex) = c.value.transpose();
    }
  }
  if (std::filesystem::exists(results / fmt::format("{}-{}.csv", prefix, parts)))
    throw InputError(fmt::format("{}: more result files than the partition's {} parts (results of another partition?)",
                                 results.string(), parts));
  if (const auto gap = std::find(seen.begin(), seen.end(), 0); gap != seen.end())
    throw InputError(
        fmt::format("{}: vertex {} has no value in any {}-RANK.csv", results.string(), gap - seen.begin(), prefix));
  if (has_u)
    d.vertex_scalars["u"] = values.col(0);
  else
    d.V = values;
  const auto warnings = write_mesh(a.out, d);
  for (const auto& w : warnings) fmt::print(stderr, "warning: {}\n", w);
  if (a.json)
    std::cout << nlohmann::json{{"vertices", d.V.rows()},
                                {"faces", d.F.rows()},
                                {"parts", parts},
                                {"field", has_u ? "u" : "positions"},
                                {"output", a.out}}
                     .dump(2)
              << std::endl;
  else
    fmt::print("{}: {} vertices, {} triangles, {} from {} parts\n", a.out, d.V.rows(), d.F.rows(),
               has_u ? "field u" : "positions", parts);
  return 0;
}

int run(const Args& a, MPI_Comm comm) {
  const bool fair = a.command == "fair";
  // Each rank assembles K from its own triangles and its ghosts'; an intrinsic Delaunay
  // operator flips edges across the whole surface, which no rank sees (docs/scaling.md).
  if (a.laplacian != "cotan")
    throw InputError(
        fmt::format("--laplacian {}: meshpde-mpi builds cotangent operators only (each rank from its "
                    "own triangles); for intrinsic Delaunay operators (auto picks them on badly shaped "
                    "meshes) run the serial `meshpde {}`",
                    a.laplacian, a.command));
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const auto t0 = std::chrono::steady_clock::now();
  // Reading: each rank its own part and the (small) constraints file; all agree on
  // failure before anything collective starts, so a bad part stops the run, not hangs it.
  MeshPart part;
  std::vector<InterpolationConstraint> cons;
  std::string error;
  try {
    part = read_partition_part(a.dir, rank);
    if (part.parts != size)
      throw InputError(fmt::format("{}: the partition has {} parts; run it with mpirun -n {} (not {})", a.dir,
                                   part.parts, part.parts, size));
    const long long n = part.global_vertices;
    if (!fair) cons = parse_constraints(vertex_index(n), read_file(a.constraints), 1, a.constraints);
  } catch (const std::exception& e) {
    error = e.what();
  }
  if (any_rank(!error.empty(), comm)) {
    report_errors(error, comm);
    return 1;
  }
  DistributedResult r;
  try {
    const DistributedSolveParams params{
        .g1 = a.g1, .g2 = a.g2, .tolerance = a.rtol, .max_iterations = a.max_iterations};
    r = fair ? distributed_fair(part, a.fixed, a.order, params, comm)
             : distributed_interpolate(part, cons, params, comm);
  } catch (const Error& e) {
    // The solve's own errors (bad constraints, no convergence) are the same on every
    // rank; anything else ends the whole run rather than leave the others waiting.
    if (rank == 0) fmt::print(stderr, "meshpde-mpi: error: {}\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "meshpde-mpi: error: rank {}: {}\n", rank, e.what());
    MPI_Abort(comm, 1);
  }
  // Each rank writes its own vertices' values, in the input's numbering.
  const std::filesystem::path out(a.out);
  error.clear();
  try {
    std::filesystem::create_directories(out);
    std::string text = fair ? "vertex,x,y,z\n" : "vertex,u\n";
    for (int i = 0; i < part.owned; ++i) {
      text += fmt::format("{}", part.original_id[i]);
      for (Eigen::Index c = 0; c < r.values.cols(); ++c) text += fmt::format(",{:.17g}", r.values(i, c));
      text += '\n';
    }
    write_file_atomically(out / fmt::format("{}-{}.csv", fair ? "positions" : "u", rank), text);
  } catch (const std::exception& e) {
    error = e.what();
  }
  if (any_rank(!error.empty(), comm)) {
    report_errors(error, comm);
    return 1;
  }
  // The report: every rank's share gathered on rank 0.
  const double mine[7] = {static_cast<double>(r.rank.owned),
                          static_cast<double>(r.rank.ghosts),
                          r.rank.ghost_fraction,
                          r.rank.setup_seconds,
                          r.rank.solve_seconds,
                          r.rank.peak_rss_mb,
                          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
  std::vector<double> all(static_cast<std::size_t>(7 * size));
  MPI_Gather(mine, 7, MPI_DOUBLE, all.data(), 7, MPI_DOUBLE, 0, comm);
  if (rank != 0) return 0;
  nlohmann::json per_rank = nlohmann::json::array();
  double setup = 0, solve = 0, total = 0, ghosts = 0;
  for (int k = 0; k < size; ++k) {
    const double* x = all.data() + 7 * k;
    per_rank.push_back({{"rank", k},
                        {"vertices", static_cast<long long>(x[0])},
                        {"ghosts", static_cast<long long>(x[1])},
                        {"ghost_fraction", x[2]},
                        {"setup_seconds", x[3]},
                        {"solve_seconds", x[4]},
                        {"peak_rss_mb", x[5]}});
    setup = std::max(setup, x[3]);
    solve = std::max(solve, x[4]);
    total = std::max(total, x[6]);
    ghosts += x[1];
  }
  if (a.json) {
    nlohmann::json report{{"laplacian", "cotan"},
                          {"vertices", part.global_vertices},
                          {"ranks", size},
                          {"preconditioner", r.preconditioner},
                          {"ghost_fraction", ghosts / static_cast<double>(part.global_vertices)},
                          {"result",
                           {{"seconds", total},
                            {"setup_seconds", setup},
                            {"solve_seconds", solve},
                            {"cg_iterations", r.iterations},
                            {"relative_residual", r.relative_residual}}},
                          {"per_rank", per_rank},
                          {"output", out.string()}};
    if (fair) {
      report["order"] = a.order;
      report["fixed"] = a.fixed;
    } else {
      report["constraints"] = cons.size();
      report["g1"] = a.g1;
      report["g2"] = a.g2;
    }
    std::cout << report.dump(2) << std::endl;
  } else {
    fmt::print(
        "{} vertices on {} ranks: {} CG iterations ({}), relative residual {:.2g}, set-up {:.3f} s, solve "
        "{:.3f} s; {} in {}/{}-RANK.csv\n",
        part.global_vertices, size, r.iterations, r.preconditioner, r.relative_residual, setup, solve,
        fair ? "positions" : "values", out.string(), fair ? "positions" : "u");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int code = 0;
  try {
    meshpde::PetscScope petsc(&argc, &argv);  // MPI too; PETSc options (-ksp_monitor ...) pass through
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    CLI::App app{"meshpde-mpi: distributed solves over MPI on a mesh cut by `meshpde partition`"};
    app.allow_extras();
    app.require_subcommand(1);
    Args a;
    auto common = [&a](CLI::App* cmd, const std::string& output) {
      cmd->allow_extras();
      cmd->add_option("DIR", a.dir, "The partitioned folder (meshpde partition MESH --parts N -o DIR)")->required();
      cmd->add_option("--rtol", a.rtol, "CG's relative residual")->capture_default_str();
      cmd->add_option("--max-iterations", a.max_iterations, "CG's limit")->capture_default_str();
      cmd->add_option("-o,--output", a.out, "Output folder: " + output)->required();
      cmd->add_flag("--json", a.json, "Print a JSON report (rank 0)");
      cmd->add_option("--laplacian", a.laplacian,
                      "The operators: cotan only here (auto and intrinsic are the serial meshpde's)")
          ->capture_default_str();
      cmd->callback([&a, cmd] { a.command = cmd->get_name(); });
    };
    auto* interp =
        app.add_subcommand("interpolate", "Spread scalar values given at a few vertices: (g1 K + g2 K D K) u = 0");
    common(interp, "u-RANK.csv, \"vertex,u\" for each rank's vertices (the input's numbering)");
    interp->add_option("--constraints", a.constraints, "CSV (vertex,value) or JSON, vertex indices of the input mesh")
        ->required();
    interp->add_option("--g1", a.g1, "Laplacian weight")->capture_default_str();
    interp->add_option("--g2", a.g2, "bi-Laplacian weight")->capture_default_str();
    auto* fair = app.add_subcommand("fair", "Membrane (order 1) or thin-plate (order 2) fairing with vertices held");
    common(fair, "positions-RANK.csv, \"vertex,x,y,z\" for each rank's vertices (the input's numbering)");
    fair->add_option("--fixed", a.fixed, "boundary, halfspace:NX,NY,NZ:D or all (repeatable: their union)")->required();
    fair->add_option("--order", a.order, "1: membrane, 2: thin plate")->capture_default_str();
    auto* part = app.add_subcommand("partition",
                                    "Cut a mesh into N parts for mpirun -n N (one process; as `meshpde "
                                    "partition`)");
    part->add_option("MESH", a.mesh, "Input mesh")->required();
    part->add_option("--parts", a.parts, "Number of parts (one a process of the run)")->required();
    part->add_option("-o,--output", a.out, "Output folder (created)")->required();
    part->add_flag("--json", a.json, "Print a JSON report");
    part->callback([&a] { a.command = "partition"; });
    auto* join = app.add_subcommand("join",
                                    "Join a run's result files into one mesh (one process): u-RANK.csv as the vertex "
                                    "field u, positions-RANK.csv as the positions");
    join->add_option("DIR", a.dir, "The partitioned folder the run read")->required();
    join->add_option("RESULTS", a.results, "The run's output folder (its -o)")->required();
    join->add_option("-o,--output", a.out, "Output mesh (.ply keeps the field u; .vtp too with meshpde::medical)")
        ->required();
    join->add_flag("--json", a.json, "Print a JSON report");
    join->callback([&a] { a.command = "join"; });
    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      // (rank 0 speaks for all)
      if (rank == 0) return meshpde::cli::usage_error(app, e, "meshpde-mpi", argc, argv);
      return e.get_exit_code() == 0 ? 0 : 2;
    }
    code = a.command == "partition" ? run_partition(a) : a.command == "join" ? run_join(a) : run(a, MPI_COMM_WORLD);
  } catch (const std::exception& e) {
    fmt::print(stderr, "meshpde-mpi: error: {}\n", e.what());
    return 1;
  }
  return code;
}
