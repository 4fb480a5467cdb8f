#include "solver/polynomial_surface.hpp"

#include <cmath>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

PolynomialSurface::PolynomialSurface(const Vector3d& origin, double rotation_z,
                                     const double (&c)[kMaxDegree + 1][kMaxDegree + 1])
    : origin_(origin), cos_(std::cos(rotation_z)), sin_(std::sin(rotation_z)) {
  if (!origin.allFinite() || !std::isfinite(rotation_z)) {
    Throw<InputError>("PolynomialSurface", "origin = (", origin(0), ", ", origin(1), ", ", origin(2),
                      ") m, rotation_z = ", rotation_z, " rad; must be finite");
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

bool PolynomialSurface::Evaluate(double x, double y, HeightSample* s) const { return HeightTpl(x, y, s); }

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
