// Lower cap of an ellipsoid: a femoral condyle closer to anatomy than a sphere
// (general contact kernel; reference-data/scenes/anatomical_surfaces.yaml).
//   P = C + A s,  A = Q diag(a, b, c),  |s| = 1,
// semi-axes (a, b, c) along the columns of the orientation Q, centre C, in the femur's
// frame. Height-field chart: the lower root z of (P − C)ᵀ M (P − C) = 1, M = A⁻ᵀ A⁻¹, on a
// vertical line (domain: |∇h| ≤ 1e3, like SphereCap). Regular chart: s(u, v) of
// UnitSphereChart (height_field.hpp), regular across the sagittal rim. Convex: the point
// with a given normal is closed form, s = −Aᵀ n / |Aᵀ n|.
#pragma once

#include <tuple>

#include "solver/height_field.hpp"
#include "solver/surface_parameters.hpp"

namespace kneedyn {

class EllipsoidCap final : public ChartTplSurface<EllipsoidCap> {
 public:
  static constexpr const char* kSceneType = "ellipsoid_cap";
  static constexpr auto kSceneParameters =
      std::make_tuple(surface_parameter::PointMm{"centre_mm"}, surface_parameter::SemiAxesMm{"semi_axes_mm"},
                      surface_parameter::RotationXyzDeg{"orientation_deg"});
  // semi_axes (a, b, c) > 0 in m; orientation: rotation from the ellipsoid's axes to the
  // bone's frame.
  EllipsoidCap(const Vector3d& centre, const Vector3d& semi_axes, const Matrix3d& orientation);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  void ChartCoordinates(const Vector3d& p, double uv[2]) const override;
  bool PointWithNormal(const Vector3d& n_up, double uv[2]) const override;
  // The regular chart in any scalar (EvaluateChart is its double instance).
  template <typename T>
  bool ChartTpl(const T& u, const T& v, ChartSampleTpl<T>* s) const {
    const Matrix3<T> A = A_.template cast<T>();
    const auto map = [&A](const Vector3<T>& x) -> Vector3<T> { return A * x; };
    return MappedUnitSphereChart(u, v, Vector3<T>(centre_.template cast<T>()), map, s);
  }

 private:
  Vector3d centre_, semi_axes_;
  Matrix3d A_, A_inv_, M_;
};

}  // namespace kneedyn
