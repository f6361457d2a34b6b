// Tissue properties: their names, brushes that paint them, and the weights they put
// on the fem operator.
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <string>

#include "correction_internal.h"
#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"

namespace meshpde {

TissueProperty parse_tissue_property(const std::string& text) {
  for (const TissueProperty t :
       {TissueProperty::Stiffness, TissueProperty::Mass, TissueProperty::Elasticity, TissueProperty::Viscosity})
    if (text == to_string(t)) return t;
  throw InputError(fmt::format("unknown tissue property '{}' (stiffness, mass, elasticity or viscosity)", text));
}

const char* to_string(TissueProperty property) {
  switch (property) {
    case TissueProperty::Stiffness:
      return "stiffness";
    case TissueProperty::Mass:
      return "mass";
    case TissueProperty::Elasticity:
      return "elasticity";
    case TissueProperty::Viscosity:
      return "viscosity";
  }
  return "stiffness";
}

void paint_tissue(const Mesh& mesh, CorrectionParams& params, TissueProperty property, const Brush& brush) {
  if (property == TissueProperty::Stiffness) {
    apply_brush(mesh, params.stiffness, brush);
    return;
  }
  if (!(brush.value >= 0 && brush.value <= 1))
    throw InputError(fmt::format("a {} brush paints values in [0, 1], not {}", to_string(property), brush.value));
  TissueParams& t = params.tissue;
  Eigen::VectorXd& field = property == TissueProperty::Mass         ? t.mass_field
                           : property == TissueProperty::Elasticity ? t.elasticity_field
                                                                    : t.viscosity_field;
  const double scalar = property == TissueProperty::Mass         ? t.mass
                        : property == TissueProperty::Elasticity ? t.elasticity
                                                                 : t.viscosity;
  if (field.size() == 0) field = Eigen::VectorXd::Constant(mesh.num_vertices(), scalar);
  apply_brush(mesh, field, brush);
}

void paint_tissue(const Mesh& mesh, CorrectionParams& params, const std::string& text, double millimetres_per_unit) {
  try {
    TissueProperty property = TissueProperty::Stiffness;
    std::string spec = text;
    if (const auto colon = text.find(':');
        colon != std::string::npos && !text.empty() && std::isalpha(static_cast<unsigned char>(text[0]))) {
      property = parse_tissue_property(text.substr(0, colon));
      spec = text.substr(colon + 1);
    }
    Brush brush = parse_brush(mesh, spec);
    brush.radius /= millimetres_per_unit;
    paint_tissue(mesh, params, property, brush);
  } catch (const InputError& e) {
    throw InputError(fmt::format("brush '{}': {}", text, e.what()));
  }
}

}  // namespace meshpde

namespace meshpde::correction {

double tissue_at(const Eigen::VectorXd& field, double scalar, int v) {
  return field.size() ? field[v] : scalar;
}

// The weights of the Fem operator: the stiffness field times the elasticity field
// relative to p.tissue.elasticity (its largest value after normalized(); at least 1e-3,
// so that no triangle loses all stiffness). Empty when both are absent or every
// weight is 1, so that a constant elasticity field takes the scalar's path exactly.
Eigen::VectorXd operator_weights(const CorrectionParams& p, int nv) {
  const Eigen::VectorXd& e = p.tissue.elasticity_field;
  if (e.size() == 0) return p.stiffness;
  Eigen::VectorXd w = p.stiffness.size() ? p.stiffness : Eigen::VectorXd::Ones(nv);
  bool unit = p.stiffness.size() == 0;
  for (int i = 0; i < nv; ++i) {
    const double r = p.tissue.elasticity > 0 ? std::max(e[i] / p.tissue.elasticity, 1e-3) : 1.0;
    w[i] *= r;
    unit = unit && r == 1.0;
  }
  return unit ? Eigen::VectorXd() : w;
}

}  // namespace meshpde::correction
