#include "solver/ellipsoid_cap.hpp"

#include <cmath>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

EllipsoidCap::EllipsoidCap(const Vector3d& centre, const Vector3d& semi_axes,
                           const Matrix3d& orientation)
    : centre_(centre), semi_axes_(semi_axes) {
  for (int i = 0; i < 3; ++i) {
    if (!(semi_axes(i) > 0.0) || !std::isfinite(semi_axes(i))) {
      Throw<InputError>("EllipsoidCap", "semi-axis ", i, " = ", semi_axes(i), " m; must be finite and > 0");
    }
  }
  if (!centre.allFinite()) {
    Throw<InputError>("EllipsoidCap", "centre = (", centre(0), ", ", centre(1), ", ", centre(2), ") m; must be finite");
  }
  const double det = orientation.determinant();
  const double orthogonality = (orientation.transpose() * orientation - Matrix3d::Identity()).norm();
  if (!orientation.allFinite() || !(std::abs(det - 1.0) < 1e-9) || !(orthogonality < 1e-9)) {
    Throw<InputError>("EllipsoidCap", "orientation: det = ", det, ", |RᵀR − I| = ", orthogonality,
                      "; must be a finite rotation (det 1 and |RᵀR − I| < 1e-9)");
  }
  A_ = orientation * semi_axes.asDiagonal();
  A_inv_ = A_.inverse();
  M_ = A_inv_.transpose() * A_inv_;
}

// g(w) = wᵀ M w − 1 with w = P − C; on the line (x, y): M22 t² + 2 β t + γ = 0, t = z − C_z.
bool EllipsoidCap::Evaluate(double x, double y, HeightSample* s) const {
  const double dx = x - centre_.x(), dy = y - centre_.y();
  const Matrix3d& M = M_;
  const double beta = M(0, 2) * dx + M(1, 2) * dy;
  const double gamma = M(0, 0) * dx * dx + 2.0 * M(0, 1) * dx * dy + M(1, 1) * dy * dy - 1.0;
  const double disc = beta * beta - M(2, 2) * gamma;
  if (!(disc > 0.0)) return false;
  const double t = (-beta - std::sqrt(disc)) / M(2, 2);
  const Vector3d w(dx, dy, t);
  const Vector3d grad_g = 2.0 * (M * w);  // (g_x, g_y, g_z); g_z < 0 on the lower cap
  const double gz = grad_g(2);
  const double hx = -grad_g(0) / gz, hy = -grad_g(1) / gz;
  if (!(std::hypot(hx, hy) <= 1.0e3)) return false;  // keep away from the rim (as SphereCap)
  s->value = centre_.z() + t;
  s->gradient[0] = hx;
  s->gradient[1] = hy;
  // Second implicit derivatives; g's second derivatives are 2 M.
  const double gxx = 2 * M(0, 0), gxy = 2 * M(0, 1), gyy = 2 * M(1, 1);
  const double gxz = 2 * M(0, 2), gyz = 2 * M(1, 2), gzz = 2 * M(2, 2);
  s->hessian[0] = -(gxx + 2 * gxz * hx + gzz * hx * hx) / gz;
  s->hessian[1] = -(gxy + gxz * hy + gyz * hx + gzz * hx * hy) / gz;
  s->hessian[2] = -(gyy + 2 * gyz * hy + gzz * hy * hy) / gz;
  return true;
}

void EllipsoidCap::ChartCoordinates(const Vector3d& p, double uv[2]) const {
  UnitSphereChartCoordinates(A_inv_ * (p - centre_), uv);
}

// P_u × P_v = det(A) A⁻ᵀ (s_u × s_v) = −det(A) cos u A⁻ᵀ s: parallel to n when s ∝ −Aᵀ n.
bool EllipsoidCap::PointWithNormal(const Vector3d& n_up, double uv[2]) const {
  UnitSphereChartCoordinates(-(A_.transpose() * n_up), uv);
  return true;
}

std::string EllipsoidCap::Describe() const {
  return StrCat("ellipsoid_cap(semi_axes=(", MToMm(semi_axes_.x()), ", ", MToMm(semi_axes_.y()), ", ",
                MToMm(semi_axes_.z()), ") mm, centre=(", MToMm(centre_.x()), ", ", MToMm(centre_.y()),
                ", ", MToMm(centre_.z()), ") mm)");
}

}  // namespace kneedyn
