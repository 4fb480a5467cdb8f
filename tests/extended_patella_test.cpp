// The patella's equilibrium and the articular surfaces in a wide scalar (quadruple precision,
// ε = 1.9e-34; long double, ε = 1.1e-19): solver/patella_extended.hpp, solver/surface_wide.hpp.
// Independent reasons:
//  - the refined solution satisfies the 17 equations (PatellaResiduals, evaluated in the wide
//    scalar) to ≤ 1e-30 in quadruple precision: the equations themselves, not the solver's
//    own convergence test;
//  - it agrees with the double Newton solve to that solve's accuracy (the same equations
//    solved independently in double), and the tendon force through ComputeAppliedWrench
//    (the guard that refused a wide scalar) with the double one;
//  - each surface's chart in quadruple precision satisfies Taylor's theorem to third order,
//    |P(u + δ) − P(u) − P_u δ − ½ P_uu δ²| = O(δ³) ≈ 1e-24 at δ = 1e-8: a chart lifted from a
//    double sample is off by its round-off (~1e-18 m) and fails this by six orders; a sphere's
//    chart lies on the sphere, |P − C| = r, to quadruple round-off;
//  - the wide chart agrees with the double one to double round-off.
#include <gtest/gtest.h>

#include <cmath>

#include "benchmarks/float128_scalar.hpp"
#include "scene/scene.hpp"
#include "solver/dynamics.hpp"
#include "solver/ellipsoid_cap.hpp"
#include "solver/patella_extended.hpp"
#include "solver/polynomial_surface.hpp"
#include "solver/surface_wide.hpp"
#include "test_support.hpp"

namespace kneedyn {
namespace {

using Q = bench::Float128;
using LD = long double;

double D(const Q& x) { return x.convert_to<double>(); }
double D(LD x) { return static_cast<double>(x); }

const Scene& PatellaScene() {
  static const Scene scene = LoadScene(test_support::ScenesDir() + "/patellofemoral_impact.yaml");
  return scene;
}

// Tibial poses near the scene's start: the start itself, flexed by 2° and 5°, shifted.
std::vector<Vector6d> TibialPoses() {
  const Vector6d start = PatellaScene().model.patella->start_q;
  std::vector<Vector6d> poses = {start};
  for (double degrees : {2.0, 5.0}) {
    Vector6d q = start;
    q(kAlpha) += DegToRad(degrees);
    poses.push_back(q);
  }
  Vector6d shifted = start;
  shifted(kX0) += 0.5e-3;
  shifted(kY0) -= 0.3e-3;
  shifted(kGamma) += DegToRad(1.0);
  poses.push_back(shifted);
  return poses;
}

template <typename T>
double MaxResidual(const Patella& patella, const Vector3<T>& tuberosity_F, const T* x) {
  T r[kPatellaUnknowns];
  EXPECT_TRUE(PatellaResiduals(patella, tuberosity_F, x, r));
  double worst = 0.0;
  for (const T& v : r) worst = std::max(worst, std::abs(D(v)));
  return worst;
}

TEST(ExtendedPatella, Float128SolveHasResidualBelow1e30AndAgreesWithDouble) {
  const Patella& patella = *PatellaScene().model.patella;
  for (const Vector6d& q_d : TibialPoses()) {
    const Vector3d tuberosity_d = TuberosityInF(patella, PoseFromCoordinates(q_d));
    PatellaGuess guess_d;
    SolvePatella(patella, tuberosity_d, "test", &guess_d);
    const double residual_d = PatellaResidualNorm(patella, tuberosity_d, guess_d.x);

    const Vector6<Q> q = q_d.cast<Q>();
    const Vector3<Q> tuberosity = TuberosityInF(patella, PoseFromCoordinates(q));
    PatellaGuess guess;
    Q x[kPatellaUnknowns];
    const int iterations = SolvePatellaExtended(patella, tuberosity, "test", &guess, x);
    EXPECT_LE(iterations, 5) << "iterative refinement with the double Jacobian: a few iterations";
    const double residual = MaxResidual(patella, tuberosity, x);
    EXPECT_LT(residual, 1e-30) << "double solve's residual " << residual_d;
    EXPECT_GT(residual_d, residual * 1e10) << "the double solve stops at double round-off";
    for (int i = 0; i < kPatellaUnknowns; ++i) {
      EXPECT_NEAR(D(x[i]), guess_d.x[i], 1e-12 * (1.0 + std::abs(guess_d.x[i]))) << PatellaUnknownName(i);
    }
  }
}

TEST(ExtendedPatella, LongDoubleSolveHasResidualAtLongDoubleRoundOff) {
  const Patella& patella = *PatellaScene().model.patella;
  for (const Vector6d& q_d : TibialPoses()) {
    const Vector3<LD> tuberosity = TuberosityInF(patella, PoseFromCoordinates(Vector6<LD>(q_d.cast<LD>())));
    PatellaGuess guess;
    LD x[kPatellaUnknowns];
    SolvePatellaExtended(patella, tuberosity, "test", &guess, x);
    EXPECT_LT(MaxResidual(patella, tuberosity, x), 1e-18);
  }
}

// The tendon's pull on the tibia through the applied wrench (dynamics.hpp), in quadruple
// precision against double: the same force to double round-off.
TEST(ExtendedPatella, AppliedWrenchWithThePatellaInFloat128EqualsDouble) {
  const Model& model = PatellaScene().model;
  for (const Vector6d& q_d : TibialPoses()) {
    Data data(model);
    ComputeAppliedWrench(model, 0.01, PoseFromCoordinates(q_d), &data);
    DataTpl<Q> data_q(model);
    ComputeAppliedWrench(model, 0.01, PoseFromCoordinates(Vector6<Q>(q_d.cast<Q>())), &data_q);
    EXPECT_NEAR(D(data_q.tendon_tension), data.tendon_tension, 1e-12 * data.tendon_tension);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(D(data_q.applied_force_F(k)), data.applied_force_F(k), 1e-12 * data.applied_force_F.norm());
      EXPECT_NEAR(D(data_q.applied_moment_T(k)), data.applied_moment_T(k), 1e-12 * data.applied_moment_T.norm());
    }
  }
}

// Taylor's theorem at third order for a chart evaluated in quadruple precision, and the
// agreement of the wide chart with the double one.
void ExpectChartExactInFloat128(const HeightField& surface, double u0, double v0) {
  ChartSample s_d;
  ASSERT_TRUE(surface.EvaluateChart(u0, v0, &s_d)) << surface.Describe();
  ChartSampleTpl<Q> s0, s1;
  ASSERT_TRUE(EvaluateChartWide(surface, Q(u0), Q(v0), &s0));
  const double scale = 1.0 + s_d.p.norm();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(D(s0.p(i)), s_d.p(i), 4e-16 * scale) << surface.Describe();
    EXPECT_NEAR(D(s0.p_u(i)), s_d.p_u(i), 4e-16 * (1.0 + s_d.p_u.norm())) << surface.Describe();
    EXPECT_NEAR(D(s0.p_v(i)), s_d.p_v(i), 4e-16 * (1.0 + s_d.p_v.norm())) << surface.Describe();
  }
  const Q delta = Q(1e-8);
  for (const auto& [du, dv] : {std::pair<Q, Q>{delta, Q(0)}, {Q(0), delta}, {delta, -delta}}) {
    ASSERT_TRUE(EvaluateChartWide(surface, Q(u0) + du, Q(v0) + dv, &s1));
    const Vector3<Q> taylor = s0.p + s0.p_u * du + s0.p_v * dv +
                              (s0.p_uu * du * du + Q(2) * s0.p_uv * du * dv + s0.p_vv * dv * dv) / Q(2);
    EXPECT_LT(D((s1.p - taylor).cwiseAbs().maxCoeff()), 1e-21 * scale) << surface.Describe();
  }
}

TEST(ExtendedSurfaces, PatellarSurfacesAreExactInFloat128) {
  const Patella& patella = *PatellaScene().model.patella;
  for (const ContactPair& facet : patella.facet) {
    ExpectChartExactInFloat128(*facet.femoral_surface, 0.2, -0.6);   // trochlea: sphere cap
    ExpectChartExactInFloat128(*facet.tibial_surface, 4e-3, -7e-3);  // facet: oriented plane
    Vector3d centre;
    double radius;
    ASSERT_TRUE(facet.femoral_surface->SphereForm(&centre, &radius));
    ChartSampleTpl<Q> s;
    ASSERT_TRUE(EvaluateChartWide(*facet.femoral_surface, Q(0.2), Q(-0.6), &s));
    EXPECT_LT(D(abs((s.p - centre.cast<Q>()).norm() - Q(radius))), 1e-33);
  }
}

TEST(ExtendedSurfaces, AnatomicalSurfacesAreExactInFloat128) {
  const Scene scene = LoadScene(test_support::ScenesDir() + "/anatomical_surfaces.yaml");
  for (const ContactPair& pair : scene.model.contacts) {
    ASSERT_NE(dynamic_cast<const EllipsoidCap*>(pair.femoral_surface.get()), nullptr);
    ASSERT_NE(dynamic_cast<const PolynomialSurface*>(pair.tibial_surface.get()), nullptr);
    ExpectChartExactInFloat128(*pair.femoral_surface, 0.1, 0.3);
    ExpectChartExactInFloat128(*pair.tibial_surface, -0.012, -0.008);
  }
  // The chapter's plane (the height-field chart of PlaneSurface).
  for (const ContactPair& pair : test_support::ChapterScene().model.contacts) {
    ExpectChartExactInFloat128(*pair.tibial_surface, 0.01, -0.02);
  }
}

}  // namespace
}  // namespace kneedyn
