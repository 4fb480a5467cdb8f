#include "solver/oriented_plane.hpp"

#include <cmath>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

OrientedPlane::OrientedPlane(const Vector3d& normal, double offset) : offset_(offset) {
  const double length = normal.norm();
  if (!std::isfinite(length) || !(length > 0.0) || !std::isfinite(offset)) {
    Throw<InputError>("OrientedPlane", "normal = (", normal.x(), ", ", normal.y(), ", ", normal.z(),
                      "), offset = ", offset, " m; the normal must be finite and non-zero, the offset finite");
  }
  normal_ = normal / length;
  // e1: the coordinate axis least aligned with n̂, made orthogonal to it; e2 = n̂ × e1.
  Vector3d axis = Vector3d::UnitX();
  if (std::abs(normal_.y()) < std::abs(normal_(0)) && std::abs(normal_.y()) <= std::abs(normal_.z())) {
    axis = Vector3d::UnitY();
  } else if (std::abs(normal_.z()) < std::abs(normal_(0))) {
    axis = Vector3d::UnitZ();
  }
  e1_ = (axis - axis.dot(normal_) * normal_).normalized();
  e2_ = normal_.cross(e1_);
}

bool OrientedPlane::Evaluate(double x, double y, HeightSample* s) const {
  if (!(std::abs(normal_.z()) > 1.0e-6)) return false;
  s->value = (offset_ - normal_.x() * x - normal_.y() * y) / normal_.z();
  s->gradient[0] = -normal_.x() / normal_.z();
  s->gradient[1] = -normal_.y() / normal_.z();
  s->hessian[0] = s->hessian[1] = s->hessian[2] = 0.0;
  return true;
}

void OrientedPlane::ChartCoordinates(const Vector3d& p, double uv[2]) const {
  uv[0] = p.dot(e1_);
  uv[1] = p.dot(e2_);
}

bool OrientedPlane::PlaneForm(Vector3d* unit_normal, double* offset) const {
  *unit_normal = normal_;
  *offset = offset_;
  return true;
}

std::string OrientedPlane::Describe() const {
  return StrCat("oriented_plane(normal=(", normal_.x(), ", ", normal_.y(), ", ", normal_.z(), "), offset=",
                MToMm(offset_), " mm)");
}

}  // namespace kneedyn
