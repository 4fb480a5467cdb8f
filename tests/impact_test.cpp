// Tests of the perfectly plastic impact law (solver/impact.hpp).
//
// Validates, on the chapter scene's consistent pose (both contacts closed) with arbitrary
// approach velocities:
//  - the normal approach velocity of every impacted contact is zero afterwards, measured by
//    a central difference of the gaps along q + t q̇′ (only gaps are differenced, not G);
//  - the generalized momentum components the impulses cannot change are conserved:
//    dᵀ M Δν = 0 for every d with G d = 0, with M = diag(m, m, m, Ix, Iy, Iz) written from the
//    model's mass and inertia and G from central differences of the gaps;
//  - one contact: Δν = M⁻¹ Gᵀ P with P = −G ν / (G M⁻¹ Gᵀ) (closed form of the 7×7 system);
//  - impulses are compressive (P > 0) for approaching contacts, kinetic energy never rises.
// Does not validate: when the driver applies the impact (run.cpp, conformance tests).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "solver/consistent_init.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/impact.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;

Matrix6d HandMassMatrix(const Model& m) {
  Vector6d d;
  d << m.mass, m.mass, m.mass, m.inertia_T(0), m.inertia_T(1), m.inertia_T(2);
  return d.asDiagonal();
}

double Gap(const Model& model, int i, const Vector6d& q) {
  ContactGeometry g;
  EXPECT_TRUE(ContactKinematics(model.contacts[i], PoseFromCoordinates(q), &g));
  return g.gap;
}

// φ̇_i along q̇ by a central difference of the gap (independent of ContactConstraintRow).
double GapRateFd(const Model& model, int i, const Vector6d& q, const Vector6d& qd) {
  const double h = 1e-6;
  return (Gap(model, i, q + h * qd) - Gap(model, i, q - h * qd)) / (2.0 * h);
}

// Row G_i (in ν) by differencing the gap along q̇ = CoordinateVelocity(q, e_k).
Eigen::Matrix<double, 1, 6> RowFd(const Model& model, int i, const Vector6d& q) {
  Eigen::Matrix<double, 1, 6> G;
  for (int k = 0; k < 6; ++k) G(k) = GapRateFd(model, i, q, CoordinateVelocity(q, Vector6d::Unit(k)));
  return G;
}

double Kinetic(const Model& model, const Vector6d& q, const Vector6d& qd) {
  const Vector6d nu = GeneralizedVelocity(q, qd);
  return 0.5 * nu.dot(HandMassMatrix(model) * nu);
}

class PlasticImpact : public ::testing::Test {
 protected:
  void SetUp() override {
    ConsistentInitOptions o;
    o.form = ContactForm::kClosedForm;
    InitReport r;
    q_ = ConsistentInitialize(ChapterScene().model, ChapterScene().initial, {0, 1}, o, &r).q;
  }
  Vector6d q_;
};

TEST_F(PlasticImpact, ZeroesApproachVelocityAndConservesUnconstrainedMomentum) {
  const Model& model = ChapterScene().model;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix<double, 2, 6> G;
  G.row(0) = RowFd(model, 0, q_);
  G.row(1) = RowFd(model, 1, q_);
  const Eigen::FullPivLU<Eigen::Matrix<double, 2, 6>> lu(G);
  ASSERT_EQ(lu.rank(), 2);
  const Eigen::MatrixXd null = lu.kernel();  // 6×4: directions the impulses cannot push
  for (int trial = 0; trial < 10; ++trial) {
    Vector6d qd;
    for (int k = 0; k < 3; ++k) qd(k) = 0.2 * u(rng);      // m/s
    for (int k = 3; k < 6; ++k) qd(k) = 5.0 * u(rng);      // rad/s
    std::vector<double> P;
    const Vector6d qd_after = PlasticImpactVelocity(model, q_, qd, {0, 1}, &P);
    ASSERT_EQ(P.size(), 2u);
    const Vector6d dnu = GeneralizedVelocity(q_, qd_after) - GeneralizedVelocity(q_, qd);
    const double scale = (HandMassMatrix(model) * GeneralizedVelocity(q_, qd)).norm();
    for (int c = 0; c < 2; ++c) {
      EXPECT_NEAR(GapRateFd(model, c, q_, qd_after), 0.0, 1e-8) << "contact " << c << ", trial " << trial;
    }
    for (int k = 0; k < null.cols(); ++k) {
      const Vector6d d = null.col(k).normalized();
      EXPECT_NEAR(d.dot(HandMassMatrix(model) * dnu), 0.0, 1e-7 * scale) << "null direction " << k;
    }
    EXPECT_LE(Kinetic(model, q_, qd_after), Kinetic(model, q_, qd) * (1.0 + 1e-12));
  }
}

TEST_F(PlasticImpact, OneContactMatchesClosedFormImpulse) {
  const Model& model = ChapterScene().model;
  Vector6d qd;
  qd << 0.05, -0.1, -0.3, 2.0, 0.5, -1.0;
  for (int c = 0; c < 2; ++c) {
    std::vector<double> P;
    const Vector6d qd_after = PlasticImpactVelocity(model, q_, qd, {c}, &P);
    const Eigen::Matrix<double, 1, 6> G = RowFd(model, c, q_);
    const Matrix6d Minv = HandMassMatrix(model).inverse();
    const Vector6d nu = GeneralizedVelocity(q_, qd);
    const double P_expected = -G.dot(nu) / (G * Minv * G.transpose())(0, 0);
    ASSERT_EQ(P.size(), 1u);
    EXPECT_NEAR(P[0], P_expected, 1e-6 * std::abs(P_expected));
    const Vector6d nu_expected = nu + Minv * G.transpose() * P_expected;
    EXPECT_LT((GeneralizedVelocity(q_, qd_after) - nu_expected).norm(), 1e-6 * nu.norm());
    if (G.dot(nu) < 0.0) {
      EXPECT_GT(P[0], 0.0) << "approaching contact: compressive impulse";
    }
  }
}

TEST_F(PlasticImpact, SeparatingContactIsPulledBackToZeroRateAndNoneActiveChangesNothing) {
  const Model& model = ChapterScene().model;
  Vector6d qd;
  qd << 0.0, 0.0, 0.2, 0.0, 0.0, 0.0;
  // Without active contacts the law changes nothing.
  EXPECT_LT((PlasticImpactVelocity(model, q_, qd, {}) - qd).norm(), 1e-14);
  MechanicalState s;
  s.q = q_;
  s.qd = qd;
  s.active = {0};
  ApplyPlasticImpact(model, &s);
  EXPECT_NEAR(GapRateFd(model, 0, q_, s.qd), 0.0, 1e-8);
}

}  // namespace
}  // namespace kneedyn
