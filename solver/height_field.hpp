// Articular surfaces in the frame of the bone that carries them (femoral surfaces in F,
// tibial surfaces in T), in metres. Every surface offers two charts:
//
//  - the height-field chart z = h(x, y) of the chapter (Eqs. 1.4, 1.5): value, gradient and
//    Hessian; singular where the surface turns vertical (a sphere's equator);
//  - a regular parametric chart P(u, v) with first and second derivatives, oriented so that
//    P_u × P_v points to +z (out of a tibial surface, into a femoral one). A height field's
//    default regular chart is its height-field chart (u, v) = (x, y); curved caps override it
//    with angles that stay regular past the equator (sphere_cap, ellipsoid_cap).
//
// The templates EvaluateHeight() / EvaluateChart() lift double samples to ceres::Jet by
// the chain rule, so every Jacobian through a surface is exact without the surface knowing
// about AD. Contact kinematics for any pair of surfaces: contact_kinematics.hpp.
// Adding a surface type: one new file deriving from HeightField plus one line in
// the scene loader's surface factory (scene/surfaces.cpp, ParseSurface).
#pragma once

#include <memory>
#include <string>

#include "solver/scalar.hpp"

namespace kneedyn {

struct HeightSample {
  double value = 0.0;               // h, m
  double gradient[2] = {0.0, 0.0};  // ∂h/∂x, ∂h/∂y (dimensionless)
  double hessian[3] = {0.0, 0.0, 0.0};  // h_xx, h_xy, h_yy (1/m)
};

// One sample of a regular chart P(u, v).
struct ChartSample {
  Vector3d p = Vector3d::Zero();                       // P, m
  Vector3d p_u = Vector3d::Zero(), p_v = Vector3d::Zero();  // ∂P/∂u, ∂P/∂v
  Vector3d p_uu = Vector3d::Zero(), p_uv = Vector3d::Zero(), p_vv = Vector3d::Zero();
};

// Third derivatives of a regular chart, for the second-order lift below (the derivative of
// the contact rate term: surface_third_derivatives.cpp).
struct ChartThirdSample {
  Vector3d p_uuu = Vector3d::Zero(), p_uuv = Vector3d::Zero(), p_uvv = Vector3d::Zero(), p_vvv = Vector3d::Zero();
};

class HeightField {
 public:
  virtual ~HeightField() = default;
  // Returns false (and leaves *sample unspecified) outside the surface's domain, e.g.
  // beyond a sphere's footprint. Callers turn that into a recoverable failure.
  virtual bool Evaluate(double x, double y, HeightSample* sample) const = 0;
  // "sphere(r=21 mm, centre=(...))" for messages and summaries.
  virtual std::string Describe() const = 0;

  // Regular chart (see header comment). Default: (x, y, h(x, y)). False outside its domain.
  virtual bool EvaluateChart(double u, double v, ChartSample* sample) const;
  // Third derivatives of that chart (false outside its domain). Every surface type gives
  // them (surface_third_derivatives.cpp); the default throws SolverError naming the surface.
  virtual bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const;
  // Chart coordinates of a point on the surface (exact inverse there); for points off the
  // surface, those of a nearby surface point (a starting guess). Default: (x, y).
  virtual void ChartCoordinates(const Vector3d& p, double uv[2]) const;
  // Chart coordinates of the point whose chart normal (P_u × P_v) is parallel to n_up
  // (unit, same direction), when the surface knows it in closed form (convex caps).
  virtual bool PointWithNormal(const Vector3d& n_up, double uv[2]) const;
  // Closed-form data, when the surface is a sphere / a plane (contact_kinematics.hpp uses
  // them for the sphere-on-plane closed form). Plane: unit normal towards +z and offset d
  // with n·p = d on the plane.
  virtual bool SphereForm(Vector3d* centre, double* radius) const;
  virtual bool PlaneForm(Vector3d* unit_normal, double* offset) const;
};

// Chart choice for the chapter-form contact coordinates (contact.hpp).
enum class ContactChart {
  kRegular,      // the surface's regular chart (default)
  kHeightField,  // the chapter's (x, y) height-field chart, singular at a sphere's rim
};

// P, P_u, P_v at chart coordinates (u, v) of scalar type T (double or Jet), by the chain
// rule from one double sample: δ = u − ScalarPart(u) carries only derivatives. A scalar with
// mixed second derivatives (TimeDual over a Jet, time_dual.hpp; kOrder = 2) gets the
// second-order Taylor terms, exact there since third-order products vanish.
template <typename T, int kOrder = DerivativeOrder<T>::value>
bool EvaluateChart(const HeightField& surface, const T& u, const T& v, Vector3<T>* p,
                   Vector3<T>* p_u, Vector3<T>* p_v) {
  ChartSample s;
  if (!surface.EvaluateChart(ScalarPart(u), ScalarPart(v), &s)) return false;
  const T du = u - T(ScalarPart(u)), dv = v - T(ScalarPart(v));
  for (int i = 0; i < 3; ++i) {
    (*p)(i) = T(s.p(i)) + s.p_u(i) * du + s.p_v(i) * dv;
    (*p_u)(i) = T(s.p_u(i)) + s.p_uu(i) * du + s.p_uv(i) * dv;
    (*p_v)(i) = T(s.p_v(i)) + s.p_uv(i) * du + s.p_vv(i) * dv;
  }
  if constexpr (kOrder >= 2) {
    static_assert(kOrder == 2, "EvaluateChart: at most second derivatives");
    ChartThirdSample s3;
    if (!surface.EvaluateChartThird(ScalarPart(u), ScalarPart(v), &s3)) return false;
    const T duu = 0.5 * du * du, duv = du * dv, dvv = 0.5 * dv * dv;
    for (int i = 0; i < 3; ++i) {
      (*p)(i) += s.p_uu(i) * duu + s.p_uv(i) * duv + s.p_vv(i) * dvv;
      (*p_u)(i) += s3.p_uuu(i) * duu + s3.p_uuv(i) * duv + s3.p_uvv(i) * dvv;
      (*p_v)(i) += s3.p_uuv(i) * duu + s3.p_uvv(i) * duv + s3.p_vvv(i) * dvv;
    }
  }
  return true;
}

inline bool EvaluateHeight(const HeightField& surface, double x, double y, double* value,
                           double gradient[2]) {
  HeightSample s;
  if (!surface.Evaluate(x, y, &s)) return false;
  *value = s.value;
  gradient[0] = s.gradient[0];
  gradient[1] = s.gradient[1];
  return true;
}

// Chain rule: h(x(θ), y(θ)) and ∇h(x(θ), y(θ)) with their θ-derivatives.
template <int N>
bool EvaluateHeight(const HeightField& surface, const ceres::Jet<double, N>& x,
                    const ceres::Jet<double, N>& y, ceres::Jet<double, N>* value,
                    ceres::Jet<double, N> gradient[2]) {
  HeightSample s;
  if (!surface.Evaluate(x.a, y.a, &s)) return false;
  value->a = s.value;
  value->v = s.gradient[0] * x.v + s.gradient[1] * y.v;
  gradient[0].a = s.gradient[0];
  gradient[0].v = s.hessian[0] * x.v + s.hessian[1] * y.v;
  gradient[1].a = s.gradient[1];
  gradient[1].v = s.hessian[1] * x.v + s.hessian[2] * y.v;
  return true;
}

// Lower half of a sphere, z = l − sqrt(r² − (x − h)² − (y − k)²) (chapter Eq. 1.4).
// Centre (h, k, l), radius r, all in metres. Domain: strictly inside the footprint circle.
// The unit-sphere angle chart shared by sphere_cap and ellipsoid_cap (height_field.cpp):
// s(u, v) = (sin u, cos u sin v, −cos u cos v); false outside |u| < 80°, |v| < 170°.
bool UnitSphereChart(double u, double v, ChartSample* s);
void UnitSphereChartCoordinates(const Vector3d& s, double uv[2]);  // inverse, s ≠ 0

// Regular chart: spherical angles with the poles on the ±x axis (medial–lateral), so the
// chart is regular across the sagittal rim where flexion moves the contact:
//   P(u, v) = C + r (sin u, cos u sin v, −cos u cos v),  |u| < 80°, |v| < 170°.
class SphereCap final : public HeightField {
 public:
  SphereCap(const Vector3d& centre, double radius);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  bool EvaluateChart(double u, double v, ChartSample* sample) const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  void ChartCoordinates(const Vector3d& p, double uv[2]) const override;
  bool PointWithNormal(const Vector3d& n_up, double uv[2]) const override;
  bool SphereForm(Vector3d* centre, double* radius) const override;
  const Vector3d& centre() const { return centre_; }
  double radius() const { return radius_; }

 private:
  Vector3d centre_;
  double radius_;
};

// Plane z = slope_x x + slope_y y + offset (chapter Eq. 1.5 with the x′ slope, docs/model.md §3).
class PlaneSurface final : public HeightField {
 public:
  PlaneSurface(double slope_x, double slope_y, double offset);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  bool PlaneForm(Vector3d* unit_normal, double* offset) const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  // Unit normal (−h_x, −h_y, 1)/norm, pointing to +z (towards the femur for a tibial
  // plateau), and offset d with normal·p = d for points p on the plane.
  Vector3d UnitNormal() const;
  double NormalOffset() const;

 private:
  double slope_x_, slope_y_, offset_;
};

}  // namespace kneedyn
