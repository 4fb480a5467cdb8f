// Articular surfaces as height fields z = h(x, y) in the frame of the bone that carries
// them (femoral surfaces in F, tibial surfaces in T; chapter Eqs. 1.4, 1.5), in metres.
//
// A surface implements one small interface: value, gradient and Hessian in double. The
// template EvaluateHeight() lifts that to ceres::Jet by the chain rule, so every
// Jacobian that passes through a surface is exact without the surface knowing about AD.
// Adding a smooth height field (e.g. a polynomial fit) is one new file deriving from
// HeightField plus one line in scene.cpp's surface factory.
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

class HeightField {
 public:
  virtual ~HeightField() = default;
  // Returns false (and leaves *sample unspecified) outside the surface's domain, e.g.
  // beyond a sphere's footprint. Callers turn that into a recoverable failure.
  virtual bool Evaluate(double x, double y, HeightSample* sample) const = 0;
  // "sphere(r=21 mm, centre=(...))" for messages and summaries.
  virtual std::string Describe() const = 0;
};

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
class SphereCap final : public HeightField {
 public:
  SphereCap(const Vector3d& centre, double radius);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  const Vector3d& centre() const { return centre_; }
  double radius() const { return radius_; }

 private:
  Vector3d centre_;
  double radius_;
};

// Plane z = slope_x x + slope_y y + offset (chapter Eq. 1.5 with the x′ slope, spec §3).
class PlaneSurface final : public HeightField {
 public:
  PlaneSurface(double slope_x, double slope_y, double offset);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  // Unit normal (−h_x, −h_y, 1)/norm, pointing to +z (towards the femur for a tibial
  // plateau), and offset d with normal·p = d for points p on the plane.
  Vector3d UnitNormal() const;
  double NormalOffset() const;

 private:
  double slope_x_, slope_y_, offset_;
};

}  // namespace kneedyn
