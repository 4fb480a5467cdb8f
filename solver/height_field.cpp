#include "solver/height_field.hpp"

#include <cmath>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

SphereCap::SphereCap(const Vector3d& centre, double radius) : centre_(centre), radius_(radius) {
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    Throw<InputError>("SphereCap", "radius = ", radius, " m; must be finite and > 0");
  }
}

bool SphereCap::Evaluate(double x, double y, HeightSample* s) const {
  const double dx = x - centre_.x(), dy = y - centre_.y();
  const double r2 = radius_ * radius_;
  const double q = r2 - dx * dx - dy * dy;
  // Keep away from the rim where the gradient is infinite: |∇h| ≤ 1e3.
  if (!(q > 1.0e-6 * r2)) return false;
  const double w = std::sqrt(q);
  s->value = centre_.z() - w;
  s->gradient[0] = dx / w;
  s->gradient[1] = dy / w;
  const double w3 = q * w;
  s->hessian[0] = (r2 - dy * dy) / w3;
  s->hessian[1] = dx * dy / w3;
  s->hessian[2] = (r2 - dx * dx) / w3;
  return true;
}

std::string SphereCap::Describe() const {
  return StrCat("sphere_cap(r=", MToMm(radius_), " mm, centre=(", MToMm(centre_.x()), ", ",
                MToMm(centre_.y()), ", ", MToMm(centre_.z()), ") mm)");
}

PlaneSurface::PlaneSurface(double slope_x, double slope_y, double offset)
    : slope_x_(slope_x), slope_y_(slope_y), offset_(offset) {
  if (!std::isfinite(slope_x) || !std::isfinite(slope_y) || !std::isfinite(offset)) {
    Throw<InputError>("PlaneSurface", "non-finite plane parameter (slope_x = ", slope_x,
                      ", slope_y = ", slope_y, ", offset = ", offset, ")");
  }
}

bool PlaneSurface::Evaluate(double x, double y, HeightSample* s) const {
  s->value = slope_x_ * x + slope_y_ * y + offset_;
  s->gradient[0] = slope_x_;
  s->gradient[1] = slope_y_;
  s->hessian[0] = s->hessian[1] = s->hessian[2] = 0.0;
  return true;
}

std::string PlaneSurface::Describe() const {
  return StrCat("plane(slope_x=", slope_x_, ", slope_y=", slope_y_, ", offset=", MToMm(offset_),
                " mm)");
}

Vector3d PlaneSurface::UnitNormal() const {
  return Vector3d(-slope_x_, -slope_y_, 1.0).normalized();
}

double PlaneSurface::NormalOffset() const {
  return offset_ / std::sqrt(1.0 + slope_x_ * slope_x_ + slope_y_ * slope_y_);
}

}  // namespace kneedyn
