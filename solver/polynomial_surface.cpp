#include "solver/polynomial_surface.hpp"

#include <cmath>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

PolynomialSurface::PolynomialSurface(const Vector3d& origin, double rotation_z,
                                     const double (&c)[kMaxDegree + 1][kMaxDegree + 1])
    : origin_(origin), cos_(std::cos(rotation_z)), sin_(std::sin(rotation_z)) {
  if (!origin.allFinite() || !std::isfinite(rotation_z)) {
    Throw<InputError>("PolynomialSurface", "origin and rotation must be finite");
  }
  for (int i = 0; i <= kMaxDegree; ++i) {
    for (int j = 0; j <= kMaxDegree; ++j) {
      if (!std::isfinite(c[i][j]) || (i + j > kMaxDegree && c[i][j] != 0.0)) {
        Throw<InputError>("PolynomialSurface", "coefficient c", i, j, " = ", c[i][j],
                          "; must be finite, and zero for degree i + j > ", kMaxDegree);
      }
      c_[i][j] = c[i][j];
    }
  }
}

bool PolynomialSurface::Evaluate(double x, double y, HeightSample* s) const {
  const double dx = x - origin_.x(), dy = y - origin_.y();
  const double xi = cos_ * dx + sin_ * dy, eta = -sin_ * dx + cos_ * dy;
  // Powers and their derivatives: p[i] = ξ^i, dp[i] = i ξ^(i−1), ddp[i] = i(i−1) ξ^(i−2).
  double px[kMaxDegree + 1], py[kMaxDegree + 1];
  px[0] = py[0] = 1.0;
  for (int i = 1; i <= kMaxDegree; ++i) {
    px[i] = px[i - 1] * xi;
    py[i] = py[i - 1] * eta;
  }
  double h = 0, h_x = 0, h_y = 0, h_xx = 0, h_xy = 0, h_yy = 0;  // in (ξ, η)
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

std::string PolynomialSurface::Describe() const {
  std::string terms;
  for (int i = 0; i <= kMaxDegree; ++i) {
    for (int j = 0; i + j <= kMaxDegree; ++j) {
      if (c_[i][j] != 0.0) terms += StrCat(terms.empty() ? "" : ", ", "c", i, j, "=", c_[i][j]);
    }
  }
  return StrCat("polynomial(origin=(", MToMm(origin_.x()), ", ", MToMm(origin_.y()), ", ",
                MToMm(origin_.z()), ") mm, ", terms, " [SI])");
}

}  // namespace kneedyn
