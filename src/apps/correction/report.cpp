// A correction's report as JSON (apps/vessel_correction.h: correction_report_json):
// written once here for the command-line tool and the Python module.
#include <nlohmann/json.hpp>

#include "meshpde/apps/vessel_correction.h"
#include "meshpde/image/volume.h"

namespace meshpde {

std::string correction_report_json(const Positions& V, const Triangles& F, const CorrectionParams& p,
                                   const CorrectionResult& r, const CorrectionCaps& caps) {
  using json = nlohmann::json;
  const auto vec = [](const Eigen::Vector3d& v) { return json{v.x(), v.y(), v.z()}; };
  const auto text_or_null = [](const std::string& s) { return s.empty() ? json() : json(s); };
  json j = {{"moved_vertices", r.moved_vertices},
            {"max_displacement", r.max_displacement},
            {"region_vertices", r.region.size()},
            {"new_self_intersections", r.new_self_intersections},
            {"time_ms", r.time_ms},
            {"method", to_string(p.method)},
            {"boundary", to_string(p.boundary)},
            {"dynamic", p.dynamic},
            {"laplacian", to_string(r.laplacian)},
            {"laplacian_reason", r.laplacian_reason},
            {"relative_residual", r.relative_residual},
            {"condition_estimate", r.condition_estimate},
            {"error_bound", r.error_bound},
            {"accuracy_warning", text_or_null(r.accuracy_warning)},
            {"region_warning", text_or_null(r.region_warning)},
            {"handle_warning", text_or_null(r.handle_warning)},
            {"applied_fraction", r.applied_fraction},
            {"substeps", r.substeps},
            {"intersection_action", r.intersection_action},
            {"handles", p.handles.size()},
            {"handle_radius", r.handle_radius},
            {"solver", to_string(r.solver)},
            {"units", to_string(p.units)}};
  json handle_points = json::array();
  for (std::size_t i = 0; i < p.handles.size(); ++i) {
    const CorrectionHandle& h = p.handles[i];
    json hj = {{"vertex", h.vertex}, {"displacement", vec(h.displacement)}};
    // A quadratic reading uses 12 vertices at least, the corners 3, a vertex 1 (a point
    // handle held at its nearest corner, as the springs method and an unanchored region
    // do, is read there).
    const std::size_t used = i < r.handle_reading.size() ? r.handle_reading[i].size() : 1;
    hj["reading"] = used > 3 ? "quadratic" : used == 3 ? "corners" : "vertex";
    if (h.point) {
      hj["triangle"] = h.point->face;
      hj["barycentric"] = vec(h.point->bary);
      Eigen::Vector3d x = Eigen::Vector3d::Zero(), moved = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k) {
        x += h.point->bary[k] * V.row(F(h.point->face, k)).transpose();
        if (r.displacement.rows() == V.rows())
          moved += h.point->bary[k] * r.displacement.row(F(h.point->face, k)).transpose();
      }
      hj["position"] = vec(x);
      hj["corners_displacement"] = vec(moved);
      if (h.given) {
        hj["given"] = vec(*h.given);
        hj["distance_to_surface"] = (*h.given - x).norm() * millimetres_per(p.units);
      }
    }
    handle_points.push_back(hj);
  }
  j["handle_points"] = handle_points;
  json found = json::array();
  for (const Cap& c : caps.caps)
    found.push_back({{"label", c.label},
                     {"faces", c.faces.size()},
                     {"vertices", c.vertices.size()},
                     {"centre", vec(c.centre)},
                     {"normal", vec(c.normal)}});
  j["caps"] = {{"rule", caps.rule},
               {"label_array", text_or_null(caps.label_array)},
               {"held_vertices", p.held.size()},
               {"caps", found}};
  if (p.image.edges)
    j["image"] = {{"pulled_vertices", r.pulled_vertices},
                  {"outside_vertices", r.image_outside_vertices},
                  {"mean_edge_before", r.image_mean_edge_before},
                  {"mean_edge_after", r.image_mean_edge_after},
                  {"space", to_string(p.image.space)}};
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace meshpde
