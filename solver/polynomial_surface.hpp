// Polynomial height field of degree ≤ 4 in a local frame: a tibial plateau (concave
// medial, convex lateral) or a fitted femoral surface (general contact kernel;
// tests/anatomical_surfaces_test.cpp).
//   z = o_z + Σ_{i+j≤4} c_ij ξ^i η^j,  (ξ, η) = Rz(θ)ᵀ ((x, y) − (o_x, o_y)),
// in the bone's frame: local origin o, local axes turned by θ about the bone's z axis (so
// the surface stays a height field over the bone's (x, y)). Coefficients in SI
// (m^(1−i−j)). Defined everywhere; the regular chart is the height-field chart.
#pragma once

#include <tuple>

#include "solver/height_field.hpp"
#include "solver/surface_parameters.hpp"

namespace kneedyn {

class PolynomialSurface final : public HeightField {
 public:
  static constexpr int kMaxDegree = kMaxPolynomialDegree;
  static constexpr const char* kSceneType = "polynomial";
  static constexpr auto kSceneParameters =
      std::make_tuple(surface_parameter::PointMm{"origin_mm"}, surface_parameter::AngleDeg{"rotation_z_deg"},
                      surface_parameter::PolynomialCoefficientsMm{"coefficients_mm"});
  // coefficients[i][j] = c_ij for i + j ≤ 4 (others must be zero), SI.
  PolynomialSurface(const Vector3d& origin, double rotation_z,
                    const double (&coefficients)[kMaxDegree + 1][kMaxDegree + 1]);
  PolynomialSurface(const Vector3d& origin, double rotation_z, const PolynomialCoefficients& coefficients)
      : PolynomialSurface(origin, rotation_z, coefficients.c) {}
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  std::string Describe() const override;
  // The height in any scalar (Evaluate is its double instance).
  template <typename T>
  bool HeightTpl(const T& x, const T& y, HeightSampleTpl<T>* s) const {
    const T dx = x - origin_.x(), dy = y - origin_.y();
    const T xi = cos_ * dx + sin_ * dy, eta = -sin_ * dx + cos_ * dy;
    // Powers and their derivatives: p[i] = ξ^i, dp[i] = i ξ^(i−1), ddp[i] = i(i−1) ξ^(i−2).
    T px[kMaxDegree + 1], py[kMaxDegree + 1];
    px[0] = py[0] = T(1.0);
    for (int i = 1; i <= kMaxDegree; ++i) {
      px[i] = px[i - 1] * xi;
      py[i] = py[i - 1] * eta;
    }
    T h = T(0), h_x = T(0), h_y = T(0), h_xx = T(0), h_xy = T(0), h_yy = T(0);  // in (ξ, η)
    for (int i = 0; i <= kMaxDegree; ++i) {
      for (int j = 0; i + j <= kMaxDegree; ++j) {
        const double c = c_[i][j];
        if (c == 0.0) continue;
        h += c * px[i] * py[j];
        if (i >= 1) h_x += c * i * px[i - 1] * py[j];
        if (j >= 1) h_y += c * j * px[i] * py[j - 1];
        if (i >= 2) h_xx += c * i * (i - 1) * px[i - 2] * py[j];
        if (i >= 1 && j >= 1) h_xy += c * i * j * px[i - 1] * py[j - 1];
        if (j >= 2) h_yy += c * j * (j - 1) * px[i] * py[j - 2];
      }
    }
    // Back to the bone's (x, y): ∇_x = Rz ∇_ξ, H_x = Rz H_ξ Rzᵀ.
    const double C = cos_, S = sin_;
    s->value = origin_.z() + h;
    s->gradient[0] = C * h_x - S * h_y;
    s->gradient[1] = S * h_x + C * h_y;
    s->hessian[0] = C * C * h_xx - 2 * C * S * h_xy + S * S * h_yy;
    s->hessian[1] = C * S * (h_xx - h_yy) + (C * C - S * S) * h_xy;
    s->hessian[2] = S * S * h_xx + 2 * C * S * h_xy + C * C * h_yy;
    return true;
  }

 private:
  Vector3d origin_;
  double cos_, sin_;
  double c_[kMaxDegree + 1][kMaxDegree + 1];
};

}  // namespace kneedyn
