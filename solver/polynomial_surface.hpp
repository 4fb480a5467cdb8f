// Polynomial height field of degree ≤ 4 in a local frame: a tibial plateau (concave
// medial, convex lateral) or a fitted femoral surface (general contact kernel;
// tests/anatomical_surfaces_test.cpp).
//   z = o_z + Σ_{i+j≤4} c_ij ξ^i η^j,  (ξ, η) = Rz(θ)ᵀ ((x, y) − (o_x, o_y)),
// in the bone's frame: local origin o, local axes turned by θ about the bone's z axis (so
// the surface stays a height field over the bone's (x, y)). Coefficients in SI
// (m^(1−i−j)). Defined everywhere; the regular chart is the height-field chart.
#pragma once

#include "solver/height_field.hpp"

namespace kneedyn {

class PolynomialSurface final : public HeightField {
 public:
  static constexpr int kMaxDegree = 4;
  // coefficients[i][j] = c_ij for i + j ≤ 4 (others must be zero), SI.
  PolynomialSurface(const Vector3d& origin, double rotation_z,
                    const double (&coefficients)[kMaxDegree + 1][kMaxDegree + 1]);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  std::string Describe() const override;

 private:
  Vector3d origin_;
  double cos_, sin_;
  double c_[kMaxDegree + 1][kMaxDegree + 1];
};

}  // namespace kneedyn
