// CorrectionSession: corrections one after another, with undo, redo and restore.
#include <fmt/format.h>

#include <algorithm>
#include <set>

#include "correction_internal.h"
#include "meshpde/core/errors.h"

namespace meshpde {

CorrectionSession::CorrectionSession(Mesh mesh)
    : mesh_(std::move(mesh)), history_{mesh_.positions()}, original_checker_(mesh_) {}

CorrectionResult CorrectionSession::apply(const CorrectionParams& params) {
  // The checker keeps the original positions; every vertex moved so far is checked
  // at its current position along with this correction's region.
  CorrectionResult r = correction::correct_vessel_impl(mesh_, params, &original_checker_, touched_);
  std::set<int> t(touched_.begin(), touched_.end());
  for (int v : r.region)
    if (r.displacement.row(v).squaredNorm() > 0) t.insert(v);
  touched_.assign(t.begin(), t.end());
  history_.resize(current_ + 1);
  history_.push_back(r.V);
  ++current_;
  mesh_.set_positions(r.V);
  return r;
}

void CorrectionSession::undo() {
  if (!can_undo()) throw InputError("nothing to undo");
  --current_;
  mesh_.set_positions(history_[current_]);
}

void CorrectionSession::redo() {
  if (!can_redo()) throw InputError("nothing to redo");
  ++current_;
  mesh_.set_positions(history_[current_]);
}

void CorrectionSession::restore(std::vector<Positions> history, std::size_t current) {
  const Positions& original = history_.front();
  if (history.empty() || current >= history.size())
    throw InputError(fmt::format("a history of {} steps cannot be at step {}", history.size(), current));
  std::vector<int> touched;
  std::vector<char> moved(static_cast<std::size_t>(original.rows()), 0);
  for (std::size_t k = 0; k < history.size(); ++k) {
    const Positions& P = history[k];
    if (P.rows() != original.rows() || !P.allFinite())
      throw InputError(fmt::format("history step {}: {} positions for {} vertices, or one not finite", k, P.rows(),
                                   original.rows()));
    if (k == 0 && P != original) throw InputError("history step 0 is not the mesh's own positions");
    for (Eigen::Index v = 0; v < P.rows(); ++v)
      if (!moved[static_cast<std::size_t>(v)] && P.row(v) != original.row(v)) {
        moved[static_cast<std::size_t>(v)] = 1;
        touched.push_back(static_cast<int>(v));
      }
  }
  std::sort(touched.begin(), touched.end());
  history_ = std::move(history);
  current_ = current;
  touched_ = std::move(touched);
  mesh_.set_positions(history_[current_]);
}

int CorrectionSession::new_self_intersections() const {
  return original_checker_.count_new(mesh_.positions(), touched_);
}

}  // namespace meshpde
