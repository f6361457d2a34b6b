// Haptic poking (Kim and Rossignac 2004 section 5.4, Fig. 12): a probe holds a surface vertex and
// moves; the surface yields on a self-adjusting active domain and pushes back.
//
// The displacement field d (#V x 3) follows PdeSession's dynamics with the contact
// vertex constrained to the probe's offset. The feedback force felt by the probe is
// minus the reaction force that holds the contact vertex (pde_session.h), so it
// points back out of an indentation. Units: force = stiffness x displacement
// (g0 in force / length^3 x area, etc.); with the defaults below, a displacement in
// mesh units gives a force in "mesh units" too: scale it to your device.
//
// Solver (HapticParams::solver). Factored, the default: each step is two triangular
// sweeps with a sparse Cholesky factor of the step matrix on the active domain
// (pde/step_factor.h), a cost that does not depend on the probe's motion. The domain
// is adjusted by PdeSession's self-adjusting rule, but a change takes effect only when
// the factor of the new domain is ready: a second thread builds it while the servo
// keeps stepping on the last one (the domain lags its growth by one build, a few
// milliseconds); the servo never waits for the builder, not even for its lock.
// Before the first factor of a touch is ready, the step uses CG on the few seed rings.
// A caller that steps faster than real time (an offline replay, a notebook, a test)
// sets wait_for_factors: step() then waits for a factor being built,
// so its domain keeps up with its steps and every run gives the same forces.
// Cg: Jacobi-CG every step on a domain that adjusts itself after every step; fast on
// average, but its iteration count, hence its time, has no bound.
//
// Threading: step() may be called directly (replay, tests), or start() runs a
// fixed-rate servo loop on its own thread that steps at `rate_hz` with a per-step
// deadline: if a CG solve cannot finish before the next tick, CG stops with its current
// iterate (the best available force is returned) and the miss is counted. Probe
// commands (touch, move_probe, release) and force reads are thread-safe.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/pde_session.h"

namespace meshpde {

/// How a haptic step is solved (see the top of this file).
enum class HapticSolver {
  Factored,  ///< a factor of the step matrix on the domain, rebuilt on a second thread
  Cg,        ///< Jacobi-CG every step
};

/// Defaults give a light, critically damped surface (settles in about 0.3 s)
/// whose step system is well conditioned at 1 kHz: the inertia term (alpha + b1 dt) M
/// dominates (b2 + dt) dt Kt by a few times, so CG needs about ten iterations.
struct HapticParams {
  /// The decay length `influence` = 0 stands for, in mean edge lengths.
  static constexpr double default_influence_edges = 3;
  double influence = 0;  ///< decay length of a poke (mesh units); 0: default_influence_edges mean edge lengths
  double stiffness = 1;  ///< g0, the foundation; g2 = g0 influence^4 follows from it
  double mass = 1e-2;    ///< alpha: inertia
  double damping = 0.2;  ///< b1: critical damping of the foundation mode (b1 = 2 sqrt(alpha g0)): no overshoot
  double stiffness_damping = 1e-3;  ///< b2
  /// The active domain stops growing where the motion falls below this fraction of the
  /// largest motion (DomainOptions::grow_fraction).
  double domain_tolerance = 5e-2;
  double rate_hz = 1000;  ///< servo rate of start()
  HapticSolver solver = HapticSolver::Factored;
  /// Factored only: step() waits for a factor being built (never the servo of start()).
  /// For callers that step faster than real time: without it their domain falls behind
  /// by as many steps as a build takes them, and the surface is too stiff meanwhile.
  bool wait_for_factors = false;
  /// Per step, relative to the step's right-hand side. 5e-4 keeps the force trajectory of a
  /// moving probe within 1 % of a 1e-10 solve (tested; measured 0.65 %; 1e-3 gives 1.2 %).
  /// Past its deadline a step still iterates to 1e-2 (late_tolerance): on a machine
  /// too slow for the rate the servo runs late (counted as misses) but stays stable.
  CgOptions cg{.tolerance = 5e-4, .max_iterations = 500, .deadline = {}, .min_iterations = 2, .late_tolerance = 1e-2};
  /// log() keeps the last this many samples (room reserved when the session is made,
  /// about 100 bytes a sample), so a session can run for hours.
  std::size_t max_log = 200000;
};

/// One servo step, as logged by the session.
struct HapticSample {
  double time = 0;                                  ///< seconds since start (step count x period)
  Eigen::Vector3d probe = Eigen::Vector3d::Zero();  ///< probe offset from the contact's rest position
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< feedback force on the probe
  double latency_us = 0;                            ///< wall time of the step
  int free_vertices = 0;                            ///< active domain size
  int cg_iterations = 0;
  bool factored = false;  ///< solved with the domain's factor (HapticSolver::Factored), not CG
  bool missed = false;    ///< the step overran its period (or hit the deadline)
  /// Where the step's time went (us; latency_us is their sum and the bookkeeping
  /// between): taking a new domain's factor (install_us, with new_factor set when one
  /// was taken), the solve (solve_us), proposing the next domain (propose_us) and
  /// publishing the displacement (publish_us).
  bool new_factor = false;
  float install_us = 0, solve_us = 0, propose_us = 0, publish_us = 0;
};

class HapticSession {
 public:
  /// Keeps references to mesh and ops. \throw InputError for bad parameters.
  HapticSession(const Mesh& mesh, const FemOperators& ops, const HapticParams& params = {});
  ~HapticSession();
  HapticSession(const HapticSession&) = delete;
  HapticSession& operator=(const HapticSession&) = delete;

  /// Grabs vertex v (probe offset zero). \throw InputError for a bad vertex.
  void touch(int vertex);
  /// Grabs the vertex nearest to a surface point.
  void touch_point(const Eigen::Vector3d& point);
  /// Probe offset from the grabbed vertex's rest position (mesh units).
  void move_probe(const Eigen::Vector3d& offset);
  /// Lets go: the surface relaxes and the domain shrinks back.
  void release();
  bool touching() const;
  int contact_vertex() const;

  /// One step of length dt; returns the feedback force (zero when not touching). With
  /// wait_for_factors it first waits for a factor being built.
  Eigen::Vector3d step(double dt);

  /// Servo loop on its own thread at params.rate_hz; log() fills as it runs.
  void start();
  /// Stops the loop (joins the thread). Safe to call twice.
  void stop();
  bool running() const { return running_; }

  Eigen::Vector3d latest_force() const;
  /// The surface's displacement (#V x 3, mesh units) after the last step and the
  /// active domain's size, from a copy the servo publishes after each step (reading
  /// it never waits for a step; safe while the servo thread runs).
  Field displacement(int* active_vertices = nullptr) const;
  /// Active-domain size after the last step, and the 99th percentile of the last
  /// 1,000 step latencies (us): both without waiting for a step or copying the log.
  int active_vertices() const;
  double recent_p99_us() const;
  std::vector<HapticSample> log() const;
  int misses() const { return misses_; }
  /// Factors of the domain built so far (HapticSolver::Factored), and the wall time of
  /// the last build (s).
  int factorizations() const { return factorizations_; }
  double last_factor_seconds() const { return last_factor_seconds_; }
  /// Set when a factor could not be built (the session then steps with CG): the reason.
  std::string factor_error() const;
  const PdeSession& pde() const { return *session_; }

 private:
  void servo_loop();
  void publish();  // called under mutex_ after each step
  Eigen::Vector3d step_locked(double dt, std::chrono::steady_clock::time_point deadline);

  // HapticSolver::Factored: the next domain and its factor, built by builder_loop().
  struct FactorJob {
    std::vector<int> free, to_rest;
    double dt = 0;
    int contact = -1;
    PdeCoefficients coefficients;
  };
  struct FactorReady {
    std::shared_ptr<const StepFactor> factor;  // of the new domain: factor->vertices()
    std::vector<int> to_rest;
    int contact = -1;
  };
  bool install_ready_factor(int contact);  // true when a factor was taken
  std::unique_lock<std::mutex> servo_builder_lock();
  void propose_factor(double dt, int contact);
  FactorReady build_factor(FactorJob job);
  void builder_loop();
  const Mesh& mesh_;
  const FemOperators& ops_;
  HapticParams params_;
  std::unique_ptr<PdeSession> session_;
  mutable std::mutex mutex_;
  std::atomic<int> contact_{-1};  // written under mutex_; read without it by touching()
  Eigen::Vector3d probe_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_ = Eigen::Vector3d::Zero();
  std::vector<HapticSample> log_;  // a ring once full: log_next_ is the oldest sample
  std::size_t log_next_ = 0;
  double time_ = 0;
  std::atomic<bool> running_{false};
  std::atomic<int> misses_{0};
  std::thread thread_;
  mutable std::mutex io_mutex_;  // probe_, force_, recent_: never held across a step
  std::vector<float> recent_;    // ring of the last step latencies (us)
  std::size_t recent_next_ = 0;
  mutable std::mutex snapshot_mutex_;
  Field snapshot_;
  std::vector<int> published_;
  int snapshot_active_ = 0;
  // Factor builder: job_ waits for the builder, ready_ for the stepping thread.
  mutable std::mutex builder_mutex_;
  std::condition_variable builder_cv_, built_cv_;
  std::optional<FactorJob> job_;
  std::optional<FactorReady> ready_;
  std::vector<std::shared_ptr<const StepFactor>> retired_;  // freed by the builder
  bool building_ = false, builder_stop_ = false;
  std::string factor_error_;
  std::thread builder_;
  std::atomic<int> factorizations_{0};
  std::atomic<double> last_factor_seconds_{0};
};

/// A point of a recorded probe path: at time `t` (seconds) the probe is `offset` (mesh
/// units) away from the contact vertex's rest position.
struct ProbePathPoint {
  double t = 0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
};

/// Parses a probe path CSV: one "t,dx,dy,dz" a line (commas or whitespace between
/// them), times strictly increasing; `#` starts a comment; a header line is allowed.
/// `name` (the file) is quoted in errors with the line.
/// \throw InputError for a malformed line, a non-finite number, times that do not
///        increase, or no point at all.
std::vector<ProbePathPoint> parse_probe_path(const std::string& text, const std::string& name);

/// `meshpde poke`'s default path: a press into the surface at `vertex`, towards its
/// neighbours' centroid (inward on a convex patch; +z where there is no such
/// direction), to `depth_edges` mean edge lengths over 0.5 s, then held until 0.7 s.
std::vector<ProbePathPoint> press_path(const Mesh& mesh, int vertex, double depth_edges);

/// The probe's offset at time t: linear between the path's points, held before the
/// first and after the last. \pre the path is not empty and its times increase.
Eigen::Vector3d probe_path_at(const std::vector<ProbePathPoint>& path, double t);

}  // namespace meshpde
