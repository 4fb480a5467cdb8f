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
// Adding a surface type: a file pair deriving from HeightField that declares its scene
// name and parameters (surface_parameters.hpp), one line in surface_types.hpp, and its name
// and keys in reference-data/scenes/README.md and fuzz/yaml.dict (README, "Layout").
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <tuple>
#include <type_traits>

#include "solver/scalar.hpp"
#include "solver/surface_parameters.hpp"

namespace kneedyn {

// Samples in a scalar T: double for the surfaces' virtual interface, a wide scalar (long
// double, quadruple) for the extended-precision references (EvaluateChart below).
template <typename T>
struct HeightSampleTpl {
  T value = T(0.0);                       // h, m
  T gradient[2] = {T(0.0), T(0.0)};       // ∂h/∂x, ∂h/∂y (dimensionless)
  T hessian[3] = {T(0.0), T(0.0), T(0.0)};  // h_xx, h_xy, h_yy (1/m)
};
using HeightSample = HeightSampleTpl<double>;

// One sample of a regular chart P(u, v).
template <typename T>
struct ChartSampleTpl {
  Vector3<T> p = Vector3<T>::Zero();                          // P, m
  Vector3<T> p_u = Vector3<T>::Zero(), p_v = Vector3<T>::Zero();  // ∂P/∂u, ∂P/∂v
  Vector3<T> p_uu = Vector3<T>::Zero(), p_uv = Vector3<T>::Zero(), p_vv = Vector3<T>::Zero();
};
using ChartSample = ChartSampleTpl<double>;

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

// A surface whose regular chart is one template, Surface::ChartTpl(u, v, sample) in any
// scalar (wide scalars: EvaluateChartWide, surface_wide.hpp); EvaluateChart is its double
// instance, so the chart has one formula per surface type.
template <typename Surface>
class ChartTplSurface : public HeightField {
 public:
  bool EvaluateChart(double u, double v, ChartSample* sample) const override {
    return static_cast<const Surface&>(*this).ChartTpl(u, v, sample);
  }
};

// The default regular chart (u, v) = (x, y) of a height field, in any scalar, from its
// height sample (HeightField::EvaluateChart is the double instance's equivalent).
template <typename T>
void HeightFieldChart(const T& u, const T& v, const HeightSampleTpl<T>& h, ChartSampleTpl<T>* s) {
  s->p = Vector3<T>(u, v, h.value);
  s->p_u = Vector3<T>(T(1.0), T(0.0), h.gradient[0]);
  s->p_v = Vector3<T>(T(0.0), T(1.0), h.gradient[1]);
  s->p_uu = Vector3<T>(T(0.0), T(0.0), h.hessian[0]);
  s->p_uv = Vector3<T>(T(0.0), T(0.0), h.hessian[1]);
  s->p_vv = Vector3<T>(T(0.0), T(0.0), h.hessian[2]);
}

// Chart choice for the chapter-form contact coordinates (contact.hpp).
enum class ContactChart {
  kRegular,      // the surface's regular chart (default)
  kHeightField,  // the chapter's (x, y) height-field chart, singular at a sphere's rim
};

// P, P_u, P_v at chart coordinates (u, v) of scalar type T (double or Jet), by the chain
// rule from one double sample: δ = u − ScalarPart(u) carries only derivatives. A scalar with
// mixed second derivatives (TimeDual over a Jet, time_dual.hpp; kOrder = 2) gets the
// second-order Taylor terms, exact there since third-order products vanish.
// A wide scalar (neither double nor a derivative over double: long double, quadruple) is not
// lifted from a double sample, whose round-off (1e-16 of P) would be its error: the surface
// evaluates its chart in T (EvaluateChartWide, surface_wide.hpp).
template <typename T>
bool EvaluateChartWide(const HeightField& surface, const T& u, const T& v, ChartSampleTpl<T>* sample);

// A ceres::Jet over double (EvaluateChart's direct lift).
/// \cond INTERNAL
template <typename T>
struct IsJetOverDouble : std::false_type {};
template <int N>
struct IsJetOverDouble<ceres::Jet<double, N>> : std::true_type {};
/// \endcond

template <typename T, int kOrder = DerivativeOrder<T>::value>
bool EvaluateChart(const HeightField& surface, const T& u, const T& v, Vector3<T>* p,
                   Vector3<T>* p_u, Vector3<T>* p_v) {
  if constexpr (!IsDoubleOrJet<T>::value) {
    ChartSampleTpl<T> wide;
    if (!EvaluateChartWide(surface, u, v, &wide)) return false;
    *p = wide.p;
    *p_u = wide.p_u;
    *p_v = wide.p_v;
    return true;
  } else {
    ChartSample s;
    if (!surface.EvaluateChart(ScalarPart(u), ScalarPart(v), &s)) return false;
    if constexpr (std::is_same_v<T, double>) {  // δ = 0: the sample itself
      *p = s.p;
      *p_u = s.p_u;
      *p_v = s.p_v;
      return true;
    } else if constexpr (IsJetOverDouble<T>::value && kOrder == 1) {
      // A Jet: the values are the sample's and the derivative parts the chain rule's, as the
      // general lines below give them, without their Jet temporaries (the exact Jacobian
      // evaluates four charts per contact; ~4× fewer instructions per call).
      for (int i = 0; i < 3; ++i) {
        (*p)(i).a = s.p(i);
        (*p)(i).v = s.p_u(i) * u.v + s.p_v(i) * v.v;
        (*p_u)(i).a = s.p_u(i);
        (*p_u)(i).v = s.p_uu(i) * u.v + s.p_uv(i) * v.v;
        (*p_v)(i).a = s.p_v(i);
        (*p_v)(i).v = s.p_uv(i) * u.v + s.p_vv(i) * v.v;
      }
      return true;
    }
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

// The height-field chart in a wide scalar (neither double nor Jet), evaluated in T by the
// surface's own template (EvaluateHeightWide, surface_wide.hpp).
template <typename T>
bool EvaluateHeightWide(const HeightField& surface, const T& x, const T& y, HeightSampleTpl<T>* sample);
template <typename T, typename = std::enable_if_t<!IsDoubleOrJet<T>::value>>
bool EvaluateHeight(const HeightField& surface, const T& x, const T& y, T* value, T gradient[2]) {
  HeightSampleTpl<T> s;
  if (!EvaluateHeightWide(surface, x, y, &s)) return false;
  *value = s.value;
  gradient[0] = s.gradient[0];
  gradient[1] = s.gradient[1];
  return true;
}

// Lower half of a sphere, z = l − sqrt(r² − (x − h)² − (y − k)²) (chapter Eq. 1.4).
// Centre (h, k, l), radius r, all in metres. Domain: strictly inside the footprint circle.
// The unit-sphere angle chart shared by sphere_cap and ellipsoid_cap (height_field.cpp):
// s(u, v) = (sin u, cos u sin v, −cos u cos v); false outside |u| < 80°, |v| < 170°.
constexpr double kUnitSphereChartMaxLatitude = 80.0 * 3.14159265358979323846 / 180.0;    // |u|, rad
constexpr double kUnitSphereChartMaxLongitude = 170.0 * 3.14159265358979323846 / 180.0;  // |v|, rad
template <typename T>
bool UnitSphereChart(const T& u, const T& v, ChartSampleTpl<T>* s) {
  using std::abs;
  using std::cos;
  using std::sin;
  if (!(abs(u) < kUnitSphereChartMaxLatitude) || !(abs(v) < kUnitSphereChartMaxLongitude)) return false;
  const T su = sin(u), cu = cos(u), sv = sin(v), cv = cos(v);
  s->p = Vector3<T>(su, cu * sv, -cu * cv);
  s->p_u = Vector3<T>(cu, -su * sv, su * cv);
  s->p_v = Vector3<T>(T(0.0), cu * cv, cu * sv);
  s->p_uu = -s->p;
  s->p_uv = Vector3<T>(T(0.0), -su * cv, -su * sv);
  s->p_vv = Vector3<T>(T(0.0), -cu * sv, cu * cv);
  return true;
}
void UnitSphereChartCoordinates(const Vector3d& s, double uv[2]);  // inverse, s ≠ 0
// A cap P = C + L s of the unit-sphere chart under a linear map L (r I for sphere_cap, A for
// ellipsoid_cap): P and its derivatives, each derivative mapped by L. False outside the domain.
template <typename T, typename LinearMap>
bool MappedUnitSphereChart(const T& u, const T& v, const Vector3<T>& centre, const LinearMap& map,
                           ChartSampleTpl<T>* s) {
  if (!UnitSphereChart(u, v, s)) return false;
  s->p = centre + map(s->p);
  s->p_u = map(s->p_u);
  s->p_v = map(s->p_v);
  s->p_uu = map(s->p_uu);
  s->p_uv = map(s->p_uv);
  s->p_vv = map(s->p_vv);
  return true;
}

// Regular chart: spherical angles with the poles on the ±x axis (medial–lateral), so the
// chart is regular across the sagittal rim where flexion moves the contact:
//   P(u, v) = C + r (sin u, cos u sin v, −cos u cos v),  |u| < 80°, |v| < 170°.
class SphereCap final : public ChartTplSurface<SphereCap> {
 public:
  static constexpr const char* kSceneType = "sphere_cap";
  static constexpr auto kSceneParameters =
      std::make_tuple(surface_parameter::PointMm{"centre_mm"}, surface_parameter::PositiveLengthMm{"radius_mm"});
  SphereCap(const Vector3d& centre, double radius);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  void ChartCoordinates(const Vector3d& p, double uv[2]) const override;
  bool PointWithNormal(const Vector3d& n_up, double uv[2]) const override;
  bool SphereForm(Vector3d* centre, double* radius) const override;
  // The regular chart in any scalar (EvaluateChart is its double instance).
  template <typename T>
  bool ChartTpl(const T& u, const T& v, ChartSampleTpl<T>* s) const {
    const T radius = T(radius_);
    const auto scale = [&radius](const Vector3<T>& x) -> Vector3<T> { return radius * x; };
    return MappedUnitSphereChart(u, v, Vector3<T>(centre_.template cast<T>()), scale, s);
  }
  const Vector3d& centre() const { return centre_; }
  double radius() const { return radius_; }

 private:
  Vector3d centre_;
  double radius_;
};

// Plane z = slope_x x + slope_y y + offset (chapter Eq. 1.5 with the x′ slope, docs/model.md §3).
class PlaneSurface final : public HeightField {
 public:
  static constexpr const char* kSceneType = "plane";
  static constexpr auto kSceneParameters =
      std::make_tuple(surface_parameter::Slope{"slope_x", false}, surface_parameter::Slope{"slope_y", true},
                      surface_parameter::LengthMm{"offset_mm"});
  PlaneSurface(double slope_x, double slope_y, double offset);
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  bool PlaneForm(Vector3d* unit_normal, double* offset) const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  // The height in any scalar (Evaluate is its double instance).
  template <typename T>
  bool HeightTpl(const T& x, const T& y, HeightSampleTpl<T>* s) const {
    s->value = slope_x_ * x + slope_y_ * y + offset_;
    s->gradient[0] = T(slope_x_);
    s->gradient[1] = T(slope_y_);
    s->hessian[0] = s->hessian[1] = s->hessian[2] = T(0.0);
    return true;
  }
  // Unit normal (−h_x, −h_y, 1)/norm, pointing to +z (towards the femur for a tibial
  // plateau), and offset d with normal·p = d for points p on the plane.
  Vector3d UnitNormal() const;
  double NormalOffset() const;

 private:
  double slope_x_, slope_y_, offset_;
};

}  // namespace kneedyn
