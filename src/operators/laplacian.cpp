#include "meshpde/operators/laplacian.h"

#include <fmt/format.h>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

LaplacianKind parse_laplacian_kind(const std::string& text) {
  if (text == "auto") return LaplacianKind::Auto;
  if (text == "cotan") return LaplacianKind::Cotan;
  if (text == "intrinsic" || text == "intrinsic-delaunay") return LaplacianKind::IntrinsicDelaunay;
  throw InputError(fmt::format("unknown Laplacian '{}' (expected auto, cotan or intrinsic)", text));
}

const char* to_string(LaplacianKind kind) {
  switch (kind) {
    case LaplacianKind::Auto:
      return "auto";
    case LaplacianKind::Cotan:
      return "cotan";
    case LaplacianKind::IntrinsicDelaunay:
      return "intrinsic";
  }
  return "?";
}

MeshOperators build_mesh_operators(const Mesh& mesh, LaplacianKind kind, const Eigen::VectorXd& vertex_weights) {
  MeshOperators out;
  if (kind == LaplacianKind::Auto) {
    const MeshReport r = analyze(mesh);
    const ShapeWarningThresholds t;
    if (r.nonmanifold_edges > 0 || r.nonmanifold_vertices > 0) {
      kind = LaplacianKind::IntrinsicDelaunay;
      out.reason = "non-manifold mesh";
    } else if (r.area_ratio > 0 && (r.min_angle_deg < t.min_angle_deg || r.area_ratio > t.area_ratio)) {
      kind = LaplacianKind::IntrinsicDelaunay;
      out.reason =
          fmt::format("badly shaped (smallest angle {:.3g} deg, area ratio {:.3g})", r.min_angle_deg, r.area_ratio);
    } else {
      kind = LaplacianKind::Cotan;
      out.reason = "well shaped";
    }
  }
  out.kind = kind;
  if (kind == LaplacianKind::IntrinsicDelaunay) {
    IntrinsicDelaunayOptions o;
    o.vertex_weights = vertex_weights;
    IntrinsicOperators io = build_intrinsic_delaunay_operators(mesh, o);
    out.mesh = std::move(io.operator_mesh);
    out.ops = std::move(io.ops);
    out.stats = io.stats;
  } else {
    OperatorOptions o;
    if (vertex_weights.size()) o.face_weights = vertex_to_face_average(mesh, vertex_weights);
    out.mesh = mesh;
    out.ops = build_cotan_operators(mesh, o);
  }
  return out;
}

std::shared_ptr<const MeshOperators> OperatorCache::operators(const Mesh& mesh) {
  if (!operators_) {
    operators_ = std::make_shared<const MeshOperators>(build_mesh_operators(mesh, kind_));
    ++builds_;
    if (operators_->kind == LaplacianKind::Cotan) cotan_ = operators_;  // the same bundle serves both
  }
  return operators_;
}

std::shared_ptr<const MeshOperators> OperatorCache::cotan(const Mesh& mesh) {
  if (!cotan_) {
    cotan_ = std::make_shared<const MeshOperators>(build_mesh_operators(mesh, LaplacianKind::Cotan));
    ++builds_;
  }
  return cotan_;
}

void OperatorCache::refresh() {
  operators_.reset();
  cotan_.reset();
}

}  // namespace meshpde
