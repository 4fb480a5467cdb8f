#include "solver/height_field.hpp"

#include <algorithm>
#include <cmath>

#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

bool HeightField::EvaluateChart(double u, double v, ChartSample* s) const {
  HeightSample h;
  if (!Evaluate(u, v, &h)) return false;
  HeightFieldChart(u, v, h, s);
  return true;
}

void HeightField::ChartCoordinates(const Vector3d& p, double uv[2]) const {
  uv[0] = p.x();
  uv[1] = p.y();
}

bool HeightField::PointWithNormal(const Vector3d&, double*) const { return false; }
bool HeightField::SphereForm(Vector3d*, double*) const { return false; }
bool HeightField::PlaneForm(Vector3d*, double*) const { return false; }

void UnitSphereChartCoordinates(const Vector3d& s, double uv[2]) {
  const Vector3d d = s.normalized();
  uv[0] = std::asin(std::max(-1.0, std::min(1.0, d.x())));
  uv[1] = std::atan2(d.y(), -d.z());
}

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

void SphereCap::ChartCoordinates(const Vector3d& p, double uv[2]) const {
  UnitSphereChartCoordinates(p - centre_, uv);
}

// The chart normal P_u × P_v is −cos u · s: the point with normal n_up has s = −n_up.
bool SphereCap::PointWithNormal(const Vector3d& n_up, double uv[2]) const {
  UnitSphereChartCoordinates(-n_up, uv);
  return true;
}

bool SphereCap::SphereForm(Vector3d* centre, double* radius) const {
  *centre = centre_;
  *radius = radius_;
  return true;
}

bool PlaneSurface::PlaneForm(Vector3d* unit_normal, double* offset) const {
  *unit_normal = UnitNormal();
  *offset = NormalOffset();
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

bool PlaneSurface::Evaluate(double x, double y, HeightSample* s) const { return HeightTpl(x, y, s); }

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
