// The conformance suite of the surface types: every scene type of solver/surface_types.hpp,
// read through the scene loader from sample values of its declared parameters
// (solver/surface_parameters.hpp), must
//  - load as that type, with the file's mm and degrees converted to SI: its charts equal
//    those of the surface constructed directly from the same values in SI;
//  - refuse a mapping without one of its required keys, naming the key, and load without
//    an optional one;
//  - give first and second chart derivatives that match central differences of the chart,
//    third derivatives (EvaluateChartThird) that match differences of the second, P_u × P_v
//    towards +z, and an inverse (ChartCoordinates) that returns the chart coordinates;
//  - evaluate its chart in long double (EvaluateChartWide, the extended-precision path) to
//    the double chart's value within double round-off.
// A new surface type is covered by adding it to the list; a new parameter kind needs its
// sample below (the test does not compile without one).
// Does not validate: contact kinematics between surface pairs (contact_kinematics_test.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "scene/internal/sections.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"
#include "solver/surface_types.hpp"
#include "solver/surface_wide.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

namespace sp = surface_parameter;

// A sample of each parameter kind: the YAML text a scene would hold, and the value in SI the
// constructor should receive (converted here by hand from the documented units).
struct Sample {
  std::string yaml;
  bool required;
};

Sample SampleOf(const sp::PointMm&) { return {"[1.5, -2.0, 3.0]", true}; }
Vector3d SiOf(const sp::PointMm&) { return Vector3d(1.5e-3, -2.0e-3, 3.0e-3); }
Sample SampleOf(const sp::SemiAxesMm&) { return {"[20.0, 24.0, 21.0]", true}; }
Vector3d SiOf(const sp::SemiAxesMm&) { return Vector3d(20.0e-3, 24.0e-3, 21.0e-3); }
Sample SampleOf(const sp::PositiveLengthMm&) { return {"20.0", true}; }
double SiOf(const sp::PositiveLengthMm&) { return 20.0e-3; }
Sample SampleOf(const sp::LengthMm&) { return {"-5.0", true}; }
double SiOf(const sp::LengthMm&) { return -5.0e-3; }
Sample SampleOf(const sp::Slope& p) { return {p.optional ? "-0.2" : "0.3", !p.optional}; }
double SiOf(const sp::Slope& p) { return p.optional ? -0.2 : 0.3; }
Sample SampleOf(const sp::AngleDeg&) { return {"10.0", false}; }
double SiOf(const sp::AngleDeg&) { return 10.0 * kPi / 180.0; }
Sample SampleOf(const sp::RotationXyzDeg&) { return {"[5.0, -3.0, 10.0]", false}; }
Matrix3d SiOf(const sp::RotationXyzDeg&) {  // about x, then y, then z of the bone's frame
  const double d = kPi / 180.0;
  return (Eigen::AngleAxisd(10.0 * d, Vector3d::UnitZ()) * Eigen::AngleAxisd(-3.0 * d, Vector3d::UnitY()) *
          Eigen::AngleAxisd(5.0 * d, Vector3d::UnitX()))
      .toRotationMatrix();
}
Sample SampleOf(const sp::PolynomialCoefficientsMm&) { return {"{c10: 0.3, c20: 0.008, c02: 0.01, c11: 0.002, c40: 1.0e-6}", true}; }
PolynomialCoefficients SiOf(const sp::PolynomialCoefficientsMm&) {  // c_ij in mm^(1-i-j) → m^(1-i-j)
  PolynomialCoefficients c;
  c.c[1][0] = 0.3;
  c.c[2][0] = 0.008e3;
  c.c[0][2] = 0.01e3;
  c.c[1][1] = 0.002e3;
  c.c[4][0] = 1.0e-6 * 1e9;
  return c;
}

template <typename Surface>
struct Parameters {
  std::vector<std::string> keys;
  std::vector<Sample> samples;
};

template <typename Surface>
Parameters<Surface> ParametersOf() {
  Parameters<Surface> out;
  std::apply([&out](const auto&... p) { ((out.keys.push_back(p.key), out.samples.push_back(SampleOf(p))), ...); },
             Surface::kSceneParameters);
  return out;
}

// The type's mapping with every sample value, but the key `without` (empty: all keys).
template <typename Surface>
std::string Mapping(const std::string& without = "") {
  const Parameters<Surface> params = ParametersOf<Surface>();
  std::string text = std::string("{type: ") + Surface::kSceneType;
  for (size_t i = 0; i < params.keys.size(); ++i) {
    if (params.keys[i] != without) text += ", " + params.keys[i] + ": " + params.samples[i].yaml;
  }
  return text + "}";
}

// The surface through the scene loader: a compartment whose two surfaces are the mapping.
template <typename Surface>
std::shared_ptr<const HeightField> Load(const std::string& mapping) {
  const scene_detail::Field f =
      scene_detail::ParseYaml("{femoral_surface: " + mapping + ", tibial_surface: " + mapping + "}", "sample.yaml");
  return scene_detail::ParseCompartment(f).femoral;
}

template <typename Surface>
std::shared_ptr<const HeightField> ConstructedInSi() {
  return std::apply([](const auto&... p) { return std::make_shared<Surface>(SiOf(p)...); }, Surface::kSceneParameters);
}

// Chart coordinates to sample: ±0.03 around the origin (rad for angle charts, m for height fields).
std::vector<std::array<double, 2>> ChartPoints() {
  std::vector<std::array<double, 2>> points;
  for (double u : {-0.03, -0.011, 0.0, 0.017, 0.03}) {
    for (double v : {-0.025, 0.0, 0.013, 0.029}) points.push_back({u, v});
  }
  return points;
}

template <typename Surface>
class SurfaceTypes : public ::testing::Test {};

template <typename... Surfaces>
::testing::Types<Surfaces...> GtestTypes(SurfaceTypeList<Surfaces...>);
using SceneTypes = decltype(GtestTypes(SceneSurfaceTypes{}));
TYPED_TEST_SUITE(SurfaceTypes, SceneTypes);

TYPED_TEST(SurfaceTypes, LoadsAsItsTypeWithTheValuesInSi) {
  using Surface = TypeParam;
  const std::shared_ptr<const HeightField> loaded = Load<Surface>(Mapping<Surface>());
  ASSERT_NE(dynamic_cast<const Surface*>(loaded.get()), nullptr) << Surface::kSceneType << ": " << loaded->Describe();
  const std::shared_ptr<const HeightField> direct = ConstructedInSi<Surface>();
  for (const auto& [u, v] : ChartPoints()) {
    ChartSample a, b;
    ASSERT_TRUE(loaded->EvaluateChart(u, v, &a)) << Surface::kSceneType;
    ASSERT_TRUE(direct->EvaluateChart(u, v, &b)) << Surface::kSceneType;
    EXPECT_LT((a.p - b.p).norm(), 1e-15) << Surface::kSceneType;
    EXPECT_LT((a.p_u - b.p_u).norm() + (a.p_v - b.p_v).norm(), 1e-13) << Surface::kSceneType;
    EXPECT_LT((a.p_uu - b.p_uu).norm() + (a.p_uv - b.p_uv).norm() + (a.p_vv - b.p_vv).norm(),
              1e-12 * (1.0 + b.p_uu.norm() + b.p_vv.norm()))
        << Surface::kSceneType;
  }
}

TYPED_TEST(SurfaceTypes, RefusesAMissingRequiredKeyAndLoadsWithoutAnOptionalOne) {
  using Surface = TypeParam;
  const Parameters<Surface> params = ParametersOf<Surface>();
  for (size_t i = 0; i < params.keys.size(); ++i) {
    const std::string mapping = Mapping<Surface>(params.keys[i]);
    if (!params.samples[i].required) {
      EXPECT_NO_THROW(Load<Surface>(mapping)) << mapping;
      continue;
    }
    try {
      Load<Surface>(mapping);
      ADD_FAILURE() << mapping << " loaded without " << params.keys[i];
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(params.keys[i]), std::string::npos) << e.what();
    }
  }
  // An unknown key is refused, naming it.
  std::string mapping = Mapping<Surface>();
  mapping.insert(mapping.size() - 1, ", not_a_key: 1.0");
  try {
    Load<Surface>(mapping);
    ADD_FAILURE() << mapping << " loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not_a_key"), std::string::npos) << e.what();
  }
}

TYPED_TEST(SurfaceTypes, ChartDerivativesMatchDifferences) {
  using Surface = TypeParam;
  const std::shared_ptr<const HeightField> surface = Load<Surface>(Mapping<Surface>());
  const double h = 1e-5;
  for (const auto& [u, v] : ChartPoints()) {
    ChartSample c;
    ChartThirdSample c3;
    ASSERT_TRUE(surface->EvaluateChart(u, v, &c)) << surface->Describe();
    ASSERT_TRUE(surface->EvaluateChartThird(u, v, &c3)) << surface->Describe();
    const double scale = 1.0 + c.p_u.norm() + c.p_v.norm() + c.p_uu.norm() + c.p_vv.norm();
    for (int dir = 0; dir < 2; ++dir) {
      const double du = dir == 0 ? h : 0.0, dv = dir == 0 ? 0.0 : h;
      ChartSample plus, minus;
      ASSERT_TRUE(surface->EvaluateChart(u + du, v + dv, &plus));
      ASSERT_TRUE(surface->EvaluateChart(u - du, v - dv, &minus));
      const auto d = [h](const Vector3d& a, const Vector3d& b) -> Vector3d { return (a - b) / (2 * h); };
      EXPECT_LT((d(plus.p, minus.p) - (dir == 0 ? c.p_u : c.p_v)).norm(), 1e-8 * scale) << surface->Describe();
      EXPECT_LT((d(plus.p_u, minus.p_u) - (dir == 0 ? c.p_uu : c.p_uv)).norm(), 1e-7 * scale) << surface->Describe();
      EXPECT_LT((d(plus.p_v, minus.p_v) - (dir == 0 ? c.p_uv : c.p_vv)).norm(), 1e-7 * scale) << surface->Describe();
      // Third derivatives: ∂/∂u of (P_uu, P_uv, P_vv) = (P_uuu, P_uuv, P_uvv); ∂/∂v = (P_uuv, P_uvv, P_vvv).
      const Vector3d d_uu = d(plus.p_uu, minus.p_uu), d_uv = d(plus.p_uv, minus.p_uv), d_vv = d(plus.p_vv, minus.p_vv);
      const double tol = 1e-6 * (scale + c3.p_uuu.norm() + c3.p_vvv.norm());
      EXPECT_LT((d_uu - (dir == 0 ? c3.p_uuu : c3.p_uuv)).norm(), tol) << surface->Describe();
      EXPECT_LT((d_uv - (dir == 0 ? c3.p_uuv : c3.p_uvv)).norm(), tol) << surface->Describe();
      EXPECT_LT((d_vv - (dir == 0 ? c3.p_uvv : c3.p_vvv)).norm(), tol) << surface->Describe();
    }
    EXPECT_GT(c.p_u.cross(c.p_v).z(), 0.0) << surface->Describe();
    double back[2];
    surface->ChartCoordinates(c.p, back);
    EXPECT_NEAR(back[0], u, 1e-12) << surface->Describe();
    EXPECT_NEAR(back[1], v, 1e-12) << surface->Describe();
  }
}

TYPED_TEST(SurfaceTypes, WideChartEqualsTheDoubleChart) {
  using Surface = TypeParam;
  const std::shared_ptr<const HeightField> surface = Load<Surface>(Mapping<Surface>());
  for (const auto& [u, v] : ChartPoints()) {
    ChartSample c;
    ChartSampleTpl<long double> w;
    ASSERT_TRUE(surface->EvaluateChart(u, v, &c));
    ASSERT_TRUE(EvaluateChartWide<long double>(*surface, u, v, &w)) << surface->Describe();
    const auto gap = [](const Vector3<long double>& a, const Vector3d& b) {
      return static_cast<double>((a - b.cast<long double>()).norm());
    };
    const double scale = 1.0 + c.p.norm() + c.p_u.norm() + c.p_v.norm() + c.p_uu.norm() + c.p_vv.norm();
    EXPECT_LT(gap(w.p, c.p) + gap(w.p_u, c.p_u) + gap(w.p_v, c.p_v), 1e-14 * scale) << surface->Describe();
    EXPECT_LT(gap(w.p_uu, c.p_uu) + gap(w.p_uv, c.p_uv) + gap(w.p_vv, c.p_vv), 1e-14 * scale) << surface->Describe();
  }
}

}  // namespace
}  // namespace kneedyn
