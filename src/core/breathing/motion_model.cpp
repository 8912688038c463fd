/**
 * @file motion_model.cpp
 * @brief Vertebra displacement models (paper Eq. 6-9) and the stiffness groups they imply.
 */
#include "pedicle_drilling/core/breathing/motion_model.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace pedicle_drilling::core {

namespace {

std::string toLower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

double slopePerMm3(double q1_mm_per_ml) {
  if (q1_mm_per_ml == 0.0 || !std::isfinite(q1_mm_per_ml)) {
    throw std::invalid_argument("stiffness from slope: q1 must be finite and non-zero");
  }
  return q1_mm_per_ml / kMm3PerMl;
}

}  // namespace

std::string axisName(Axis axis) {
  switch (axis) {
    case Axis::kAP:
      return "ap";
    case Axis::kSI:
      return "si";
    case Axis::kLR:
      return "lr";
  }
  return "unknown";
}

bool parseAxis(const std::string& name, Axis* axis) {
  const std::string n = toLower(name);
  for (Axis a : kAllAxes) {
    if (n == axisName(a)) {
      *axis = a;
      return true;
    }
  }
  return false;
}

std::string modelKindName(ModelKind kind) {
  return kind == ModelKind::kLinear ? "linear" : "hysteresis";
}

bool parseModelKind(const std::string& name, ModelKind* kind) {
  if (name == "linear") {
    *kind = ModelKind::kLinear;
    return true;
  }
  if (name == "hysteresis") {
    *kind = ModelKind::kHysteresis;
    return true;
  }
  return false;
}

int numCoefficients(ModelKind kind) { return kind == ModelKind::kLinear ? 2 : 3; }

double AxisModel::predict(double tv, double dtv_dt) const {
  double d = q1 * tv + q0;
  if (kind == ModelKind::kHysteresis) d += q2 * dtv_dt;
  return d;
}

std::vector<double> AxisModel::coefficients() const {
  if (kind == ModelKind::kLinear) return {q1, q0};
  return {q1, q2, q0};
}

void AxisModel::setCoefficients(const std::vector<double>& c) {
  if (static_cast<int>(c.size()) != numCoefficients(kind)) {
    throw std::invalid_argument("AxisModel::setCoefficients: " + modelKindName(kind) +
                                " model needs " + std::to_string(numCoefficients(kind)) +
                                " coefficients, got " + std::to_string(c.size()));
  }
  q1 = c[0];
  if (kind == ModelKind::kLinear) {
    q2 = 0.0;
    q0 = c[1];
  } else {
    q2 = c[1];
    q0 = c[2];
  }
}

double AxisModel::lagSeconds() const {
  if (kind != ModelKind::kHysteresis || q1 == 0.0) return 0.0;
  return -q2 / q1;
}

double SpineGeometry::apBeamFactorMm4() const {
  const double m = disc_length_mm;
  const double l = centrum_length_mm;
  // Eq. 7 at x = m: q/(24EI) m^4 - q(l + 2m)/(12EI) m^3 + c1 m with
  // c1 = q m^3/(3EI) + q l m^2/(4EI) gives q/EI (5 m^4/24 + l m^3/6), the factor of Eq. 8.
  return 5.0 * m * m * m * m / 24.0 + l * m * m * m / 6.0;
}

double apEquivalentBendingStiffness(double q1_mm_per_ml, const SpineGeometry& geometry) {
  return geometry.apBeamFactorMm4() / slopePerMm3(q1_mm_per_ml);
}

double siEquivalentAxialStiffness(double q1_mm_per_ml) { return 1.0 / slopePerMm3(q1_mm_per_ml); }

double siAxialRigidityGroup(double q1_mm_per_ml, const SpineGeometry& geometry) {
  return 2.0 * geometry.totalDiscLengthMm() / slopePerMm3(q1_mm_per_ml);
}

double equivalentStiffness(Axis axis, double q1_mm_per_ml) {
  if (q1_mm_per_ml == 0.0) return 0.0;
  switch (axis) {
    case Axis::kAP:
      return apEquivalentBendingStiffness(q1_mm_per_ml);
    case Axis::kSI:
      return siEquivalentAxialStiffness(q1_mm_per_ml);
    case Axis::kLR:
      break;
  }
  return 0.0;
}

std::string equivalentStiffnessLabel(Axis axis) {
  switch (axis) {
    case Axis::kAP:
      return "EI*V0/(p0*b_w) mm^6";
    case Axis::kSI:
      return "E*A*V0/(2*p0*S*L) mm^2";
    case Axis::kLR:
      break;
  }
  return "";
}

}  // namespace pedicle_drilling::core
