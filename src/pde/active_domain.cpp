#include "meshpde/pde/active_domain.h"

namespace meshpde {

ActiveDomain::ActiveDomain(const Mesh& mesh)
    : mesh_(&mesh),
      state_(mesh.num_vertices(), static_cast<std::uint8_t>(VertexState::Frozen)),
      free_pos_(mesh.num_vertices(), -1),
      ring_pos_(mesh.num_vertices(), -1),
      free_neighbors_(mesh.num_vertices(), 0) {}

bool ActiveDomain::on_border(int v) const {
  if (state(v) != VertexState::Free) return false;
  for (int w : mesh_->neighbors(v))
    if (state(w) == VertexState::Frozen) return true;
  return false;
}

void ActiveDomain::ring_insert(int v) {
  if (ring_pos_[v] >= 0) return;
  ring_pos_[v] = static_cast<int>(ring_.size());
  ring_.push_back(v);
}

void ActiveDomain::ring_erase(int v) {
  const int p = ring_pos_[v];
  if (p < 0) return;
  ring_[p] = ring_.back();
  ring_pos_[ring_[p]] = p;
  ring_.pop_back();
  ring_pos_[v] = -1;
}

bool ActiveDomain::make_free(int v) {
  if (state(v) == VertexState::Free) return false;
  state_[v] = static_cast<std::uint8_t>(VertexState::Free);
  free_pos_[v] = static_cast<int>(free_.size());
  free_.push_back(v);
  ring_erase(v);
  for (int w : mesh_->neighbors(v))
    if (++free_neighbors_[w] == 1 && state(w) != VertexState::Free) ring_insert(w);
  return true;
}

void ActiveDomain::leave_free(int v) {
  const int p = free_pos_[v];
  free_[p] = free_.back();
  free_pos_[free_[p]] = p;
  free_.pop_back();
  free_pos_[v] = -1;
  for (int w : mesh_->neighbors(v))
    if (--free_neighbors_[w] == 0) ring_erase(w);
  if (free_neighbors_[v] > 0) ring_insert(v);
}

bool ActiveDomain::make_frozen(int v) {
  if (state(v) == VertexState::Frozen) return false;
  const bool was_free = state(v) == VertexState::Free;
  state_[v] = static_cast<std::uint8_t>(VertexState::Frozen);
  if (was_free) leave_free(v);
  return true;
}

bool ActiveDomain::make_constrained(int v) {
  if (state(v) == VertexState::Constrained) return false;
  const bool was_free = state(v) == VertexState::Free;
  state_[v] = static_cast<std::uint8_t>(VertexState::Constrained);
  if (was_free) leave_free(v);
  return true;
}

}  // namespace meshpde
