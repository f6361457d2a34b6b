#include "meshpde/apps/haptics.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/io/text_records.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

HapticSession::HapticSession(const Mesh& mesh, const FemOperators& ops, const HapticParams& params)
    : mesh_(mesh), ops_(ops), params_(params) {
  for (double x : {params.stiffness, params.mass, params.damping, params.stiffness_damping, params.rate_hz,
                   params.domain_tolerance})
    if (!(x >= 0) || !std::isfinite(x)) throw InputError("haptic parameters must be finite and non-negative");
  if (!(params.rate_hz > 0)) throw InputError("the servo rate must be positive");
  const double h = mean_edge_length(mesh);
  const double L = params.influence > 0 ? params.influence : HapticParams::default_influence_edges * h;
  const PdeCoefficients c{.alpha = params.mass,
                          .b1 = params.damping,
                          .b2 = params.stiffness_damping,
                          .g0 = params.stiffness,
                          .g1 = 0,
                          .g2 = params.stiffness * L * L * L * L};
  // Rest thresholds scale with the mesh: 0.1 % of an edge is "at rest". During a
  // hold they, not the growth rule, size the domain: the deformation decays like
  // exp(-r / (sqrt 2 L)): a larger threshold clamps the plate too close and stiffens the
  // force (measured: 3e-3 of an edge, 7 % too stiff; 1e-2, 17 %), a smaller one grows the
  // domain. 1e-3 keeps the settled force within 1 % of a full-mesh solve (tested).
  // Factored: the session only proposes domain changes; they take effect with the
  // factor of the new domain (install_ready_factor).
  const DomainOptions d{.self_adjusting = params.solver == HapticSolver::Cg,
                        .grow_fraction = params.domain_tolerance,
                        .rest_value = 1e-3 * h,
                        .rest_rate = 1e-2 * h,
                        .seed_rings = 2};
  session_ = std::make_unique<PdeSession>(mesh, ops, 3, c, d);
  session_->cg_options = params.cg;
  // The published copy is allocated (and its pages touched) here, not in the first step:
  // on a 2M-vertex mesh that first copy alone took 23 ms.
  snapshot_ = Field::Zero(mesh.num_vertices(), 3);
  log_.reserve(params.max_log);
  if (params.solver == HapticSolver::Factored) builder_ = std::thread([this] { builder_loop(); });
}

HapticSession::~HapticSession() {
  stop();
  {
    std::lock_guard lock(builder_mutex_);
    builder_stop_ = true;
  }
  builder_cv_.notify_all();
  if (builder_.joinable()) builder_.join();
}

std::string HapticSession::factor_error() const {
  std::lock_guard lock(builder_mutex_);
  return factor_error_;
}

std::unique_lock<std::mutex> HapticSession::servo_builder_lock() {
  // The servo never waits for the builder: a builder descheduled while it holds the lock
  // (it runs at a lower priority, on a machine with other work) would stall the servo
  // for a time slice, milliseconds. When the lock is taken, the servo leaves the
  // exchange to a later step. A caller that waits for factors (replays, tests) takes it
  // always, so its runs stay reproducible.
  if (params_.wait_for_factors) return std::unique_lock(builder_mutex_);
  return std::unique_lock(builder_mutex_, std::try_to_lock);
}

bool HapticSession::install_ready_factor(int contact) {
  const std::unique_lock lock = servo_builder_lock();
  if (!lock.owns_lock() || !ready_) return false;
  FactorReady r = std::move(*ready_);
  ready_.reset();
  std::shared_ptr<const StepFactor> retired;
  if (r.contact == contact) {  // else the probe touched elsewhere meanwhile: stale
    retired = session_->step_factor();
    session_->set_free_set(r.factor->vertices(), r.to_rest);
    session_->set_step_factor(std::move(r.factor));
  } else {
    retired = std::move(r.factor);
  }
  // Freeing a factor (megabytes) is the builder's work, not the servo's.
  if (retired) retired_.push_back(std::move(retired));
  return true;
}

void HapticSession::propose_factor(double dt, int contact) {
  // Every step, so that the rest counters advance as in a self-adjusting session.
  DomainChange change = session_->propose_domain_change();
  {
    const std::unique_lock lock = servo_builder_lock();
    if (!lock.owns_lock() || building_ || job_ || ready_ || !factor_error_.empty()) return;
  }
  const int free_now = session_->domain().num_free();
  const bool stale = !session_->step_factor_applies(dt);
  if (change.empty() && (!stale || free_now == 0)) return;
  FactorJob job;
  job.dt = dt;
  job.contact = contact;
  job.coefficients = session_->coefficients();
  std::sort(change.shrink.begin(), change.shrink.end());
  for (const int v : session_->domain().free_vertices())
    if (!std::binary_search(change.shrink.begin(), change.shrink.end(), v)) job.free.push_back(v);
  job.free.insert(job.free.end(), change.grow.begin(), change.grow.end());
  job.to_rest = std::move(change.shrink);
  const std::unique_lock lock = servo_builder_lock();
  if (!lock.owns_lock()) return;                                               // proposed again at the next step
  if (job.free.empty()) {                                                      // everything at rest: nothing to factor
    if (session_->step_factor()) retired_.push_back(session_->step_factor());  // freed by the builder
    session_->set_free_set({}, job.to_rest);
    session_->set_step_factor(nullptr);
    return;
  }
  job_ = std::move(job);
  builder_cv_.notify_one();
}

HapticSession::FactorReady HapticSession::build_factor(FactorJob job) {
  FactorReady r;
  r.factor = std::make_shared<StepFactor>(mesh_, ops_, job.coefficients, std::move(job.free), job.dt);
  ++factorizations_;
  last_factor_seconds_ = r.factor->build_seconds();
  r.to_rest = std::move(job.to_rest);
  r.contact = job.contact;
  return r;
}

void HapticSession::builder_loop() {
  // One core at most, and below the servo's priority: the servo thread must never wait
  // for this one.
  const ThreadLimit one_thread(1);
#ifdef __linux__
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
#endif
  std::unique_lock lock(builder_mutex_);
  for (;;) {
    builder_cv_.wait(lock, [&] { return builder_stop_ || job_.has_value(); });
    if (builder_stop_) return;
    std::vector<std::shared_ptr<const StepFactor>> retired;
    retired.swap(retired_);
    FactorJob job = std::move(*job_);
    job_.reset();
    building_ = true;
    lock.unlock();
    retired.clear();
    std::optional<FactorReady> r;
    std::string error;
    try {
      r = build_factor(std::move(job));
    } catch (const std::exception& e) {
      error = e.what();
    }
    lock.lock();
    building_ = false;
    if (r)
      ready_ = std::move(r);
    else
      factor_error_ = "haptic step factor: " + error + "; stepping with CG from now on";
    built_cv_.notify_all();
  }
}

void HapticSession::touch(int vertex) {
  if (vertex < 0 || vertex >= mesh_.num_vertices())
    throw InputError(fmt::format("touch: vertex {} does not exist (the mesh has {})", vertex, mesh_.num_vertices()));
  std::lock_guard lock(mutex_);
  if (contact_ >= 0) session_->release(contact_);
  contact_ = vertex;
  // The probe starts where the surface is now (it may still be moving from a past poke).
  const Eigen::Vector3d start = session_->values().row(vertex).transpose();
  {
    std::lock_guard io(io_mutex_);
    probe_ = start;
  }
  session_->constrain(vertex, std::span<const double>(start.data(), 3));
}

void HapticSession::touch_point(const Eigen::Vector3d& point) {
  int v = 0;
  (mesh_.positions().rowwise() - point.transpose()).rowwise().squaredNorm().minCoeff(&v);
  touch(v);
}

void HapticSession::move_probe(const Eigen::Vector3d& offset) {
  if (!offset.allFinite()) throw InputError("probe offset is not finite");
  // Only the small I/O lock: the next step picks the probe up, and the caller (a UI
  // thread) never waits for a step in progress.
  std::lock_guard io(io_mutex_);
  probe_ = offset;
}

void HapticSession::release() {
  std::lock_guard lock(mutex_);
  if (contact_ >= 0) session_->release(contact_);
  contact_ = -1;
  std::lock_guard io(io_mutex_);
  force_.setZero();
}

bool HapticSession::touching() const {
  return contact_ >= 0;
}

int HapticSession::contact_vertex() const {
  return contact_;
}

Eigen::Vector3d HapticSession::step(double dt) {
  std::lock_guard lock(mutex_);
  if (params_.wait_for_factors && params_.solver == HapticSolver::Factored) {
    std::unique_lock wait(builder_mutex_);
    built_cv_.wait(wait, [&] { return !building_ && !job_; });
  }
  return step_locked(dt, {});
}

Eigen::Vector3d HapticSession::step_locked(double dt, std::chrono::steady_clock::time_point deadline) {
  const auto t0 = std::chrono::steady_clock::now();
  Eigen::Vector3d probe;
  {
    std::lock_guard io(io_mutex_);
    probe = probe_;
  }
  const int contact = contact_;  // changes only under mutex_, which this step holds
  const bool factored = params_.solver == HapticSolver::Factored;
  using clock = std::chrono::steady_clock;
  const auto us_since = [](clock::time_point t) {
    return static_cast<float>(std::chrono::duration<double, std::micro>(clock::now() - t).count());
  };
  HapticSample s;
  auto t = clock::now();
  if (factored) s.new_factor = install_ready_factor(contact);
  s.install_us = us_since(t);
  if (contact >= 0) session_->constrain(contact, std::span<const double>(probe.data(), 3));
  session_->cg_options.deadline = deadline;
  t = clock::now();
  const StepResult r = session_->step(dt);
  s.solve_us = us_since(t);
  t = clock::now();
  if (factored) propose_factor(dt, contact);
  s.propose_us = us_since(t);
  const Eigen::Vector3d force =
      contact >= 0 ? Eigen::Vector3d(-session_->reaction_forces().row(0).transpose()) : Eigen::Vector3d::Zero();
  {
    std::lock_guard io(io_mutex_);
    force_ = force;
  }
  time_ += dt;
  s.time = time_;
  s.probe = probe;
  s.force = force;
  s.free_vertices = r.free_vertices;
  s.cg_iterations = r.cg.iterations;
  s.factored = r.factored;
  t = clock::now();
  publish();
  s.publish_us = us_since(t);
  s.latency_us = std::chrono::duration<double, std::micro>(clock::now() - t0).count();
  s.missed = r.cg.status == CgStatus::Deadline || s.latency_us > 1e6 * dt;
  {
    std::lock_guard io(io_mutex_);
    if (recent_.size() < 1000)
      recent_.push_back(static_cast<float>(s.latency_us));
    else
      recent_[recent_next_++ % recent_.size()] = static_cast<float>(s.latency_us);
  }
  if (s.missed) ++misses_;
  // A ring of the last max_log samples, its room reserved up front: a step never copies
  // the log (growing or halving a 200,000-sample vector moved 10-20 MB, milliseconds).
  if (log_.size() < params_.max_log) {
    log_.push_back(s);
  } else if (!log_.empty()) {
    log_[log_next_] = s;
    log_next_ = (log_next_ + 1) % log_.size();
  }
  return force;
}

void HapticSession::publish() {
  // Only rows that can have changed: the domain now and the domain at the last
  // publication (vertices that just left it keep the values they left with).
  const Field& u = session_->values();
  const auto free = session_->domain().free_vertices();
  std::lock_guard lock(snapshot_mutex_);
  if (snapshot_.rows() != u.rows()) snapshot_ = u;
  for (const int v : published_) snapshot_.row(v) = u.row(v);
  for (const int v : free) snapshot_.row(v) = u.row(v);
  for (const int v : session_->constrained_vertices()) snapshot_.row(v) = u.row(v);
  published_.assign(free.begin(), free.end());
  snapshot_active_ = static_cast<int>(free.size());
}

void HapticSession::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { servo_loop(); });
}

void HapticSession::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

void HapticSession::servo_loop() {
  const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(1.0 / params_.rate_hz));
  auto tick = std::chrono::steady_clock::now();
  while (running_) {
    const auto next = tick + period;
    {
      std::lock_guard lock(mutex_);
      // Leave a tenth of the period for bookkeeping after the solve.
      step_locked(1.0 / params_.rate_hz, next - period / 10);
    }
    tick = next;
    const auto now = std::chrono::steady_clock::now();
    if (now < tick) {
      std::this_thread::sleep_until(tick);
    } else {
      tick = now;                 // overran: start the next period now rather than bursting to catch up
      std::this_thread::yield();  // and let touch/move_probe/latest_force take the lock
    }
  }
}

Eigen::Vector3d HapticSession::latest_force() const {
  std::lock_guard io(io_mutex_);
  return force_;
}

Field HapticSession::displacement(int* active_vertices) const {
  std::lock_guard lock(snapshot_mutex_);
  if (active_vertices) *active_vertices = snapshot_active_;
  if (snapshot_.rows() == 0) return Field::Zero(mesh_.num_vertices(), 3);
  return snapshot_;
}

int HapticSession::active_vertices() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_active_;
}

double HapticSession::recent_p99_us() const {
  std::vector<float> v;
  {
    std::lock_guard io(io_mutex_);
    v = recent_;
  }
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(0.99 * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

std::vector<HapticSample> HapticSession::log() const {
  std::lock_guard lock(mutex_);
  std::vector<HapticSample> out;
  out.reserve(log_.size());
  out.insert(out.end(), log_.begin() + static_cast<std::ptrdiff_t>(log_next_), log_.end());
  out.insert(out.end(), log_.begin(), log_.begin() + static_cast<std::ptrdiff_t>(log_next_));
  return out;
}

std::vector<ProbePathPoint> parse_probe_path(const std::string& text, const std::string& name) {
  std::vector<ProbePathPoint> out;
  for_each_text_record(text, FieldSeparator::CommaOrSpace, [&](int line, const std::vector<std::string>& tok) {
    if (out.empty() && !std::isdigit(static_cast<unsigned char>(tok[0][0])) && tok[0][0] != '-' && tok[0][0] != '.')
      return;  // header
    if (tok.size() != 4) throw InputError(fmt::format("{}: line {}: expected t,dx,dy,dz", name, line));
    double v[4];
    for (int k = 0; k < 4; ++k) {
      char* end = nullptr;
      v[k] = std::strtod(tok[k].c_str(), &end);
      if (*end != '\0' || !std::isfinite(v[k]))
        throw InputError(fmt::format("{}: line {}: '{}' is not a number", name, line, tok[k]));
    }
    if (!out.empty() && v[0] <= out.back().t)
      throw InputError(fmt::format("{}: line {}: times must increase", name, line));
    out.push_back({v[0], Eigen::Vector3d(v[1], v[2], v[3])});
  });
  if (out.empty()) throw InputError(fmt::format("{}: no path points", name));
  return out;
}

std::vector<ProbePathPoint> press_path(const Mesh& mesh, int vertex, double depth_edges) {
  if (vertex < 0 || vertex >= mesh.num_vertices())
    throw InputError(fmt::format("vertex {} does not exist (the mesh has {} vertices)", vertex, mesh.num_vertices()));
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (const int w : mesh.neighbors(vertex)) n += (mesh.positions().row(w) - mesh.positions().row(vertex)).transpose();
  n = n.norm() > 0 ? n.normalized() : Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d bottom = depth_edges * mean_edge_length(mesh) * n;
  return {{0.0, Eigen::Vector3d::Zero()}, {0.5, bottom}, {0.7, bottom}};
}

Eigen::Vector3d probe_path_at(const std::vector<ProbePathPoint>& p, double t) {
  if (t <= p.front().t) return p.front().offset;
  if (t >= p.back().t) return p.back().offset;
  const auto it = std::upper_bound(p.begin(), p.end(), t, [](double x, const ProbePathPoint& q) { return x < q.t; });
  const auto& b = *it;
  const auto& a = *(it - 1);
  return a.offset + (b.offset - a.offset) * ((t - a.t) / (b.t - a.t));
}

}  // namespace meshpde
