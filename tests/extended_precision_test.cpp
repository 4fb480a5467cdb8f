// The physics in long double (x87 80-bit, ε = 1.1e-19) and the Gauss–Legendre integrator of
// the extended-precision references (benchmarks/extended_reference.hpp,
// benchmarks/gauss_legendre.hpp). Independent reasons:
//  - the long double right-hand side equals the double one to double round-off (the same
//    physics; a second copy would drift from it);
//  - identities with exact values hold to long double round-off, ~1e-18, far below double's
//    1e-16: any double literal, cast or double-only function in the path would show as 1e-16
//    (pose round trip, RᵀR = I, the angular-velocity map and its inverse);
//  - the Gauss–Legendre coefficients satisfy the order conditions Σ b_i c_i^{k−1} = 1/k
//    (k ≤ 2s) and the collocation conditions exactly; the step reproduces an exact solution.
#include <gtest/gtest.h>

#include <cmath>

#include "benchmarks/float128_scalar.hpp"
#include "benchmarks/gauss_legendre.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/consistent_init.hpp"
#include "solver/events.hpp"
#include "test_support.hpp"

namespace kneedyn {
namespace {

using LD = long double;
using Vector6L = Vector6<LD>;

Vector6d ChapterLikeState(int variant, Vector6d* qd) {
  // Poses near the chapter's start (x0, y0, z0 in m; angles in rad), flexed and moving.
  Vector6d q;
  q << 0.0015, -0.012, -0.2055, 0.35 + 0.1 * variant, 1.5707963 + 0.02, 0.03 - 0.01 * variant;
  *qd << 0.002, -0.05, 0.01, 2.5, 0.1 * variant, -0.3;
  return q;
}

TEST(ExtendedPrecision, LongDoubleRightHandSideEqualsDoubleToRoundOff) {
  const Model& model = test_support::ChapterScene().model;
  for (int variant = 0; variant < 3; ++variant) {
    for (const std::vector<int>& active : {std::vector<int>{0, 1}, std::vector<int>{0}, std::vector<int>{}}) {
      Vector6d qd;
      const Vector6d q = ChapterLikeState(variant, &qd);
      const double t = 0.03 + 0.02 * variant;  // inside the pulse
      const ConstrainedAcceleration a = SolveConstrainedAcceleration(model, t, q, qd, active);
      ConstrainedDynamicsWorkspaceTpl<LD> ws(model);
      ConstrainedAccelerationTpl<LD> al;
      SolveConstrainedAccelerationTpl<LD>(model, t, q.cast<LD>(), qd.cast<LD>(), active, {}, nullptr, &ws, &al);
      const double scale = a.qdd.cwiseAbs().maxCoeff();
      for (int i = 0; i < 6; ++i) {
        EXPECT_NEAR(static_cast<double>(al.qdd(i)), a.qdd(i), 2e-15 * scale) << "qdd " << i << " variant " << variant;
      }
      for (size_t c = 0; c < active.size(); ++c) {
        EXPECT_NEAR(static_cast<double>(al.normal_force[c]), a.normal_force[c], 2e-15 * std::abs(a.normal_force[c]) + 1e-12);
      }
      // Event functions: the same values.
      MechanicalState state;
      state.q = q;
      state.active = active;
      const std::vector<EventSpec> specs = EventsForPhase(model, test_support::ChapterScene().end, state);
      std::vector<double> normal(model.contacts.size(), 0.0);
      std::vector<LD> normal_l(model.contacts.size(), 0.0L);
      for (size_t c = 0; c < active.size(); ++c) {
        normal[active[c]] = a.normal_force[c];
        normal_l[active[c]] = al.normal_force[c];
      }
      std::vector<double> g(specs.size());
      std::vector<LD> gl(specs.size());
      EvaluateEvents(model, specs, q, normal, g.data());
      EvaluateEventsTpl<LD>(model, specs, q.cast<LD>(), PoseFromCoordinates(Vector6L(q.cast<LD>())), normal_l, gl.data());
      for (size_t k = 0; k < specs.size(); ++k) {
        EXPECT_NEAR(static_cast<double>(gl[k]), g[k], 1e-13 * (1.0 + std::abs(g[k]))) << specs[k].name;
      }
    }
  }
}

// A long double quantity that must equal a known value: its error is long double round-off.
TEST(ExtendedPrecision, ExactIdentitiesHoldToLongDoubleRoundOff) {
  Vector6d qd_d;
  const Vector6L q = ChapterLikeState(1, &qd_d).cast<LD>();
  const Vector6L qd = qd_d.cast<LD>();
  const PoseTpl<LD> pose = PoseFromCoordinates(q);
  // Rotation orthogonal, pose round trip.
  const Matrix3<LD> RtR = pose.R_FT.transpose() * pose.R_FT;
  EXPECT_LT(static_cast<double>((RtR - Matrix3<LD>::Identity()).cwiseAbs().maxCoeff()), 2e-18);
  const Vector3<LD> p_T(0.0123L, -0.0456L, 0.0789L);
  EXPECT_LT(static_cast<double>((pose.PointInT(pose.PointInF(p_T)) - p_T).cwiseAbs().maxCoeff()), 1e-19);
  // q̈ → ν̇ → q̈ through E and its closed-form inverse.
  Vector6L qdd;
  qdd << 0.1L, -2.0L, 0.3L, 40.0L, -5.0L, 7.0L;
  const Vector6L back = CoordinateAccelerationTpl(q, EulerAngleTrigOf(q), qd, GeneralizedAcceleration(q, qd, qdd));
  EXPECT_LT(static_cast<double>((back - qdd).cwiseAbs().maxCoeff() / 40.0L), 2e-18);
  // The same round trip in double is at double round-off (what the tolerance excludes).
  const Vector6d qdd_d = qdd.cast<double>();
  const Vector6d q_d = q.cast<double>();
  const Vector6d back_d = CoordinateAcceleration(q_d, qd_d, GeneralizedAcceleration(q_d, qd_d, qdd_d));
  EXPECT_GT((back_d - qdd_d).cwiseAbs().maxCoeff() / 40.0, 1e-18);
  // The closed-form contact: the femoral contact point lies on the sphere, |X − C| = r |n̂′|
  // (the stored plane normal is unit in double only: |n̂′| − 1 ~ 1e-16, the same model data
  // for every scalar type).
  const Model& model = test_support::ChapterScene().model;
  for (const ContactPair& pair : model.contacts) {
    const SphereOnPlane sop = test_support::SopOf(pair);
    const ContactGeometryTpl<LD> g = RequireContactKinematicsTpl(pair, pose, "test");
    const LD r = (g.point_F - sop.centre_F.cast<LD>()).norm();
    const LD expected = LD(sop.radius) * sop.normal_T.cast<LD>().norm();
    EXPECT_LT(static_cast<double>(std::abs(r - expected) / expected), 1e-18);
  }
}

// The same in quadruple precision (the references' scalar, ε = 1.9e-34): the right-hand
// side equals double's to double round-off, exact identities hold to ~1e-32.
TEST(ExtendedPrecision, Float128RightHandSideAndIdentities) {
  using Q = bench::Float128;
  const Model& model = test_support::ChapterScene().model;
  Vector6d qd_d;
  const Vector6d q_d = ChapterLikeState(1, &qd_d);
  const std::vector<int> active = {0, 1};
  const ConstrainedAcceleration a = SolveConstrainedAcceleration(model, 0.05, q_d, qd_d, active);
  ConstrainedDynamicsWorkspaceTpl<Q> ws(model);
  ConstrainedAccelerationTpl<Q> aq;
  const Vector6<Q> q = q_d.cast<Q>(), qd = qd_d.cast<Q>();
  SolveConstrainedAccelerationTpl<Q>(model, 0.05, q, qd, active, {}, nullptr, &ws, &aq);
  const double scale = a.qdd.cwiseAbs().maxCoeff();
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(aq.qdd(i).convert_to<double>(), a.qdd(i), 2e-15 * scale) << i;
  const PoseTpl<Q> pose = PoseFromCoordinates(q);
  const Vector3<Q> p_T(Q(0.0123), Q(-0.0456), Q(0.0789));
  EXPECT_LT(((pose.PointInT(pose.PointInF(p_T)) - p_T).cwiseAbs().maxCoeff()).convert_to<double>(), 1e-33);
  Vector6<Q> qdd;
  qdd << Q(0.1), Q(-2.0), Q(0.3), Q(40.0), Q(-5.0), Q(7.0);
  const Vector6<Q> back = CoordinateAccelerationTpl(q, EulerAngleTrigOf(q), qd, GeneralizedAcceleration(q, qd, qdd));
  EXPECT_LT(((back - qdd).cwiseAbs().maxCoeff() / Q(40)).convert_to<double>(), 1e-32);
}

TEST(GaussLegendre, CoefficientsSatisfyTheOrderConditionsInLongDouble) {
  for (int s = 1; s <= 8; ++s) {
    const bench::GaussLegendre<LD> gl(s);
    for (int k = 1; k <= 2 * s; ++k) {  // quadrature of order 2s
      LD sum = 0;
      for (int i = 0; i < s; ++i) sum += gl.weights()(i) * std::pow(gl.nodes()(i), LD(k - 1));
      EXPECT_LT(static_cast<double>(std::abs(sum - LD(1) / LD(k))), 4e-18) << "s = " << s << ", k = " << k;
    }
    for (int i = 0; i < s; ++i) {  // collocation C(s): Σ_j a_ij c_j^{k−1} = c_i^k / k
      for (int k = 1; k <= s; ++k) {
        LD sum = 0;
        for (int j = 0; j < s; ++j) sum += gl.matrix()(i, j) * std::pow(gl.nodes()(j), LD(k - 1));
        EXPECT_LT(static_cast<double>(std::abs(sum - std::pow(gl.nodes()(i), LD(k)) / LD(k))), 1e-17)
            << "s = " << s << ", i = " << i << ", k = " << k;
      }
    }
  }
}

TEST(GaussLegendre, HarmonicOscillatorToLongDoubleRoundOff) {
  // y'' = −y, y(0) = 1: y = cos t. Six stages (order 12), h = 0.05, one period.
  using V = bench::GaussLegendre<LD>::Vector;
  bench::GaussLegendre<LD> gl(6);
  const auto f = [](const LD&, const V& y, V* ydot) {
    ydot->resize(2);
    (*ydot)(0) = y(1);
    (*ydot)(1) = -y(0);
  };
  V y(2), next(2);
  y << 1, 0;
  const LD two_pi = 2 * std::acos(LD(-1));
  const int n = 126;
  const LD h = two_pi / n;
  for (int i = 0; i < n; ++i) {
    ASSERT_TRUE(gl.Step(f, LD(i) * h, y, h, &next));
    y = next;
  }
  EXPECT_LT(static_cast<double>(std::abs(y(0) - 1)), 5e-18);
  EXPECT_LT(static_cast<double>(std::abs(y(1))), 5e-18);
  // Two stages (order 4) at the same step miss by far more: the order is what reaches ε.
  bench::GaussLegendre<LD> gl4(2);
  y << 1, 0;
  for (int i = 0; i < n; ++i) {
    ASSERT_TRUE(gl4.Step(f, LD(i) * h, y, h, &next));
    y = next;
  }
  EXPECT_GT(static_cast<double>(std::abs(y(0) - 1) + std::abs(y(1))), 1e-9);
}

}  // namespace
}  // namespace kneedyn
