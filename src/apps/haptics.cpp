#include "meshpde/apps/haptics.h"

#include <fmt/format.h>

#include <chrono>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

HapticSession::HapticSession(const Mesh& mesh, const FemOperators& ops, const HapticParams& params)
    : mesh_(mesh), ops_(ops), params_(params) {
  for (double x : {params.stiffness, params.mass, params.damping, params.stiffness_damping, params.rate_hz,
                   params.domain_tolerance})
    if (!(x >= 0) || !std::isfinite(x)) throw InputError("haptic parameters must be finite and non-negative");
  if (!(params.rate_hz > 0)) throw InputError("the servo rate must be positive");
  const double h = mean_edge_length(mesh);
  const double L = params.influence > 0 ? params.influence : 3 * h;
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
  const DomainOptions d{.self_adjusting = true,
                        .grow_fraction = params.domain_tolerance,
                        .rest_value = 1e-3 * h,
                        .rest_rate = 1e-2 * h,
                        .seed_rings = 2};
  session_ = std::make_unique<PdeSession>(mesh, ops, 3, c, d);
  session_->cg_options = params.cg;
}

HapticSession::~HapticSession() {
  stop();
}

void HapticSession::touch(int vertex) {
  if (vertex < 0 || vertex >= mesh_.num_vertices())
    throw InputError(fmt::format("touch: vertex {} does not exist (the mesh has {})", vertex, mesh_.num_vertices()));
  std::lock_guard lock(mutex_);
  if (contact_ >= 0) session_->release(contact_);
  contact_ = vertex;
  // The probe starts where the surface is now (it may still be moving from a past poke).
  probe_ = session_->values().row(vertex).transpose();
  session_->constrain(vertex, std::span<const double>(probe_.data(), 3));
}

void HapticSession::touch_point(const Eigen::Vector3d& point) {
  int v = 0;
  (mesh_.positions().rowwise() - point.transpose()).rowwise().squaredNorm().minCoeff(&v);
  touch(v);
}

void HapticSession::move_probe(const Eigen::Vector3d& offset) {
  if (!offset.allFinite()) throw InputError("probe offset is not finite");
  std::lock_guard lock(mutex_);
  probe_ = offset;
}

void HapticSession::release() {
  std::lock_guard lock(mutex_);
  if (contact_ >= 0) session_->release(contact_);
  contact_ = -1;
  force_.setZero();
}

bool HapticSession::touching() const {
  std::lock_guard lock(mutex_);
  return contact_ >= 0;
}

int HapticSession::contact_vertex() const {
  std::lock_guard lock(mutex_);
  return contact_;
}

Eigen::Vector3d HapticSession::step(double dt) {
  std::lock_guard lock(mutex_);
  return step_locked(dt, {});
}

Eigen::Vector3d HapticSession::step_locked(double dt, std::chrono::steady_clock::time_point deadline) {
  const auto t0 = std::chrono::steady_clock::now();
  if (contact_ >= 0) session_->constrain(contact_, std::span<const double>(probe_.data(), 3));
  session_->cg_options.deadline = deadline;
  const StepResult r = session_->step(dt);
  force_ = contact_ >= 0 ? Eigen::Vector3d(-session_->reaction_forces().row(0).transpose()) : Eigen::Vector3d::Zero();
  time_ += dt;
  HapticSample s;
  s.time = time_;
  s.probe = probe_;
  s.force = force_;
  s.latency_us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  s.free_vertices = r.free_vertices;
  s.cg_iterations = r.cg.iterations;
  s.missed = r.cg.status == CgStatus::Deadline || s.latency_us > 1e6 * dt;
  if (s.missed) ++misses_;
  if (log_.size() >= params_.max_log)
    log_.erase(log_.begin(), log_.begin() + static_cast<std::ptrdiff_t>(log_.size() / 2));
  log_.push_back(s);
  return force_;
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
    if (now < tick)
      std::this_thread::sleep_until(tick);
    else
      tick = now;  // overran: start the next period now rather than bursting to catch up
  }
}

Eigen::Vector3d HapticSession::latest_force() const {
  std::lock_guard lock(mutex_);
  return force_;
}

Field HapticSession::displacement(int* active_vertices) const {
  std::lock_guard lock(mutex_);
  if (active_vertices) *active_vertices = static_cast<int>(session_->domain().free_vertices().size());
  return session_->values();
}

std::vector<HapticSample> HapticSession::log() const {
  std::lock_guard lock(mutex_);
  return log_;
}

}  // namespace meshpde
