// Tests of the Grood–Suntay joint coordinate system (solver/rotation.hpp, solver/pose.hpp;
// docs/model.md §2).
//
// Validates: R_FT is a proper rotation and equals Rx(−α) Ry(π/2 − β) Rz(−γ) built with
// Eigen; full extension is the identity; the analytic partials ∂R/∂(α, β, γ), the
// angular-velocity map E and the velocity-product term Ė q̇ against central finite
// differences; the JCS singularity is reported; ν ↔ q̇ and ν̇ ↔ q̈ maps invert each other.
// Does not validate: anything about the knee model (angles are random, not anatomical).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <string>

#include "solver/error.hpp"
#include "solver/pose.hpp"
#include "solver/rotation.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

constexpr int kSamples = 50;

struct Angles {
  double alpha, beta, gamma;
};

// Random JCS angles away from the singularity (β ∈ [0.2, π − 0.2]).
Angles RandomAngles(std::mt19937& rng) {
  std::uniform_real_distribution<double> any(-kPi, kPi);
  std::uniform_real_distribution<double> beta(0.2, kPi - 0.2);
  return {any(rng), beta(rng), any(rng)};
}

Vector6d RandomCoordinates(std::mt19937& rng) {
  std::uniform_real_distribution<double> pos(-0.05, 0.05);
  const Angles a = RandomAngles(rng);
  Vector6d q;
  q << pos(rng), pos(rng), pos(rng), a.alpha, a.beta, a.gamma;
  return q;
}

Vector6d RandomVector6(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Vector6d v;
  for (int i = 0; i < 6; ++i) v(i) = u(rng);
  return v;
}

// Calls check(q, q̇, rng) at kSamples random states of a generator seeded with `seed`:
// coordinates as RandomCoordinates, rates ±2 (m/s, rad/s); check may draw more from rng.
template <typename Check>
void ForRandomStates(unsigned seed, Check&& check) {
  std::mt19937 rng(seed);
  for (int s = 0; s < kSamples; ++s) {
    const Vector6d q = RandomCoordinates(rng);
    const Vector6d qd = RandomVector6(rng, 2.0);
    check(q, qd, rng);
  }
}

Matrix3d R(const Vector6d& q) { return RotationFT(q(kAlpha), q(kBeta), q(kGamma)); }

// (S(2,1), S(0,2), S(1,0)) of a (nearly) skew-symmetric matrix.
Vector3d Vee(const Matrix3d& S) {
  return Vector3d(0.5 * (S(2, 1) - S(1, 2)), 0.5 * (S(0, 2) - S(2, 0)),
                  0.5 * (S(1, 0) - S(0, 1)));
}

// Expects SolverError whose message mentions the JCS singularity.
template <typename F>
void ExpectJcsSingularity(F&& call, double beta) {
  try {
    call();
    ADD_FAILURE() << "no exception at beta = " << beta;
  } catch (const SolverError& e) {
    EXPECT_NE(std::string(e.what()).find("JCS singularity"), std::string::npos)
        << "message: " << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type at beta = " << beta << ": " << e.what();
  }
}

TEST(Rotation, IsProperOrthogonalAtRandomAngles) {
  std::mt19937 rng(1);
  for (int s = 0; s < kSamples; ++s) {
    const Angles a = RandomAngles(rng);
    const Matrix3d Rft = RotationFT(a.alpha, a.beta, a.gamma);
    EXPECT_LT((Rft.transpose() * Rft - Matrix3d::Identity()).norm(), 1e-14);
    EXPECT_NEAR(Rft.determinant(), 1.0, 1e-14);
  }
}

TEST(Rotation, EqualsElementaryRotationProductFromEigen) {
  std::mt19937 rng(2);
  for (int s = 0; s < kSamples; ++s) {
    const Angles a = RandomAngles(rng);
    const Matrix3d expected =
        (Eigen::AngleAxisd(-a.alpha, Vector3d::UnitX()) *
         Eigen::AngleAxisd(kPi / 2.0 - a.beta, Vector3d::UnitY()) *
         Eigen::AngleAxisd(-a.gamma, Vector3d::UnitZ()))
            .toRotationMatrix();
    EXPECT_LT((RotationFT(a.alpha, a.beta, a.gamma) - expected).norm(), 1e-14)
        << "alpha = " << a.alpha << ", beta = " << a.beta << ", gamma = " << a.gamma;
  }
}

TEST(Rotation, FullExtensionIsIdentity) {
  EXPECT_LT((RotationFT(0.0, kPi / 2.0, 0.0) - Matrix3d::Identity()).norm(), 1e-15);
}

TEST(Rotation, PositiveFlexionSwingsTheAnklePosteriorly) {
  // A point on the tibial axis, distal (−z′), moves towards −y (posterior) under α > 0.
  const Vector3d ankle_T(0.0, 0.0, -0.4);
  const Vector3d ankle_F = RotationFT(DegToRad(30.0), kPi / 2.0, 0.0) * ankle_T;
  EXPECT_LT(ankle_F.y(), -0.1);
}

TEST(Rotation, PartialsMatchCentralDifferences) {
  std::mt19937 rng(3);
  const double h = 1e-6;
  for (int s = 0; s < kSamples; ++s) {
    const Angles a = RandomAngles(rng);
    Matrix3d dR[3];
    RotationPartials(a.alpha, a.beta, a.gamma, dR);
    const Matrix3d fd[3] = {
        (RotationFT(a.alpha + h, a.beta, a.gamma) - RotationFT(a.alpha - h, a.beta, a.gamma)) /
            (2 * h),
        (RotationFT(a.alpha, a.beta + h, a.gamma) - RotationFT(a.alpha, a.beta - h, a.gamma)) /
            (2 * h),
        (RotationFT(a.alpha, a.beta, a.gamma + h) - RotationFT(a.alpha, a.beta, a.gamma - h)) /
            (2 * h)};
    for (int k = 0; k < 3; ++k) {
      EXPECT_LT((dR[k] - fd[k]).norm(), 1e-9) << "partial " << k << "\nanalytic\n"
                                              << dR[k] << "\nfinite difference\n"
                                              << fd[k];
    }
  }
}

TEST(AngularVelocityMap, EqualsVeeOfRtRdotAlongRandomTrajectories) {
  const double h = 1e-6;
  ForRandomStates(4, [&](const Vector6d& q, const Vector6d& qd, std::mt19937&) {
    // Ṙ at t = 0 along q(t) = q + t q̇, by central differences.
    const Matrix3d Rdot = (R(q + h * qd) - R(q - h * qd)) / (2 * h);
    const Matrix3d S = R(q).transpose() * Rdot;
    // Rᵀ Ṙ must be skew-symmetric; its vee is w_T.
    EXPECT_LT((S + S.transpose()).norm(), 1e-8);
    const Vector3d w_fd = Vee(S);
    const Vector3d w = AngularVelocityMap(q(kBeta), q(kGamma)) * qd.tail<3>();
    EXPECT_LT((w - w_fd).norm(), 1e-8) << "w = " << w.transpose()
                                       << "\nfd = " << w_fd.transpose();
    // pose.hpp's ν uses the same map.
    EXPECT_LT((AngularVelocityT(q, qd) - w_fd).norm(), 1e-8);
  });
}

TEST(AngularVelocityMap, ColumnsAreMinusJcsAxesAndDeterminantIsMinusSinBeta) {
  std::mt19937 rng(5);
  for (int s = 0; s < kSamples; ++s) {
    const Angles a = RandomAngles(rng);
    const Matrix3d Rft = RotationFT(a.alpha, a.beta, a.gamma);
    // î = femoral x axis in T components; k̂′ = tibial z′; ê2 = k̂′ × î / |k̂′ × î|.
    const Vector3d i_T = Rft.transpose() * Vector3d::UnitX();
    const Vector3d k_T = Vector3d::UnitZ();
    const Vector3d e2_T = k_T.cross(i_T).normalized();
    const Matrix3d E = AngularVelocityMap(a.beta, a.gamma);
    EXPECT_LT((E.col(0) + i_T).norm(), 1e-14);
    EXPECT_LT((E.col(1) + e2_T).norm(), 1e-14);
    EXPECT_LT((E.col(2) + k_T).norm(), 1e-14);
    EXPECT_NEAR(E.determinant(), -std::sin(a.beta), 1e-14);
  }
}

TEST(AngularVelocityMap, RateTimesRateMatchesDifferenceOfMapAlongTrajectory) {
  const double h = 1e-6;
  ForRandomStates(6, [&](const Vector6d& q, const Vector6d& qd, std::mt19937&) {
    const Vector6d qp = q + h * qd, qm = q - h * qd;
    const Vector3d qd_ang = qd.tail<3>();
    const Vector3d fd = (AngularVelocityMap(qp(kBeta), qp(kGamma)) -
                         AngularVelocityMap(qm(kBeta), qm(kGamma))) /
                        (2 * h) * qd_ang;
    const Vector3d analytic = AngularVelocityMapRateTimesRate(q(kBeta), q(kGamma), qd_ang);
    EXPECT_LT((analytic - fd).norm(), 1e-8) << "analytic = " << analytic.transpose()
                                            << "\nfd = " << fd.transpose();
  });
}

TEST(AngularVelocityMap, ThrowsSolverErrorAtJcsSingularity) {
  for (double beta : {0.0, kPi, -kPi, 1e-5, kPi - 1e-5}) {
    ExpectJcsSingularity([&] { (void)AngularVelocityMap(beta, 0.3); }, beta);
    Vector6d q = Vector6d::Zero();
    q(kBeta) = beta;
    const Vector6d qd = Vector6d::Constant(0.1);
    ExpectJcsSingularity([&] { (void)CoordinateVelocity(q, qd); }, beta);
    ExpectJcsSingularity([&] { (void)CoordinateAcceleration(q, qd, qd); }, beta);
  }
  // Regular away from it (flexion does not matter, only β).
  EXPECT_NO_THROW((void)AngularVelocityMap(kPi / 2.0, 0.0));
  EXPECT_NO_THROW((void)AngularVelocityMap(0.1, 2.0));
}

TEST(GeneralizedVelocity, CoordinateVelocityRoundTrip) {
  ForRandomStates(7, [&](const Vector6d& q, const Vector6d& qd, std::mt19937&) {
    const Vector6d nu = GeneralizedVelocity(q, qd);
    EXPECT_TRUE((nu.head<3>().array() == qd.head<3>().array()).all());
    EXPECT_LT((CoordinateVelocity(q, nu) - qd).norm(), 1e-12);
  });
}

TEST(GeneralizedAcceleration, CoordinateAccelerationRoundTrip) {
  ForRandomStates(8, [&](const Vector6d& q, const Vector6d& qd, std::mt19937& rng) {
    const Vector6d qdd = RandomVector6(rng, 20.0);
    const Vector6d nud = GeneralizedAcceleration(q, qd, qdd);
    EXPECT_LT((CoordinateAcceleration(q, qd, nud) - qdd).norm(), 1e-11);
    const Vector6d nud2 = RandomVector6(rng, 20.0);
    EXPECT_LT((GeneralizedAcceleration(q, qd, CoordinateAcceleration(q, qd, nud2)) - nud2).norm(),
              1e-11);
  });
}

TEST(GeneralizedAcceleration, EqualsTimeDerivativeOfGeneralizedVelocity) {
  // Along q(t) = q + t q̇ + t²/2 q̈, q̇(t) = q̇ + t q̈: ν̇(0) = d/dt GeneralizedVelocity.
  const double h = 1e-6;
  ForRandomStates(9, [&](const Vector6d& q, const Vector6d& qd, std::mt19937& rng) {
    const Vector6d qdd = RandomVector6(rng, 20.0);
    auto nu_at = [&](double t) {
      return GeneralizedVelocity(Vector6d(q + t * qd + 0.5 * t * t * qdd),
                                 Vector6d(qd + t * qdd));
    };
    const Vector6d fd = (nu_at(h) - nu_at(-h)) / (2 * h);
    EXPECT_LT((GeneralizedAcceleration(q, qd, qdd) - fd).norm(), 1e-7);
  });
}

// The overloads that take a pose's sines and cosines (computed once per pose) must give
// exactly what the angle overloads give: the formulations' outputs are compared byte for byte.
TEST(EulerAngleTrig, OverloadsEqualTheAngleOverloadsBitwise) {
  ForRandomStates(10, [&](const Vector6d& q, const Vector6d& qd, std::mt19937& rng) {
    const Vector6d qdd = RandomVector6(rng, 20.0);
    const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
    EXPECT_EQ(trig.sa, std::sin(q(kAlpha)));
    EXPECT_EQ(trig.cg, std::cos(q(kGamma)));
    EXPECT_TRUE(RotationFT(trig) == RotationFT(q(kAlpha), q(kBeta), q(kGamma)));
    EXPECT_TRUE(AngularVelocityMap(q(kBeta), trig) == AngularVelocityMap(q(kBeta), q(kGamma)));
    EXPECT_TRUE(AngularVelocityMapRateTimesRate(trig, Vector3d(qd.tail<3>())) ==
                AngularVelocityMapRateTimesRate(q(kBeta), q(kGamma), Vector3d(qd.tail<3>())));
    EXPECT_TRUE(GeneralizedVelocity(q, trig, qd) == GeneralizedVelocity(q, qd));
    EXPECT_TRUE(PoseFromCoordinates(q, trig).R_FT == PoseFromCoordinates(q).R_FT);
    const Vector6d nud = GeneralizedAcceleration(q, trig, qd, qdd);
    EXPECT_LT((CoordinateAcceleration(q, trig, qd, nud) - qdd).norm(), 1e-11);
    Matrix3d dR[3], dR_angles[3];
    RotationPartials(trig, dR);
    RotationPartials(q(kAlpha), q(kBeta), q(kGamma), dR_angles);
    for (int a = 0; a < 3; ++a) EXPECT_TRUE(dR[a] == dR_angles[a]);
  });
  // The singularity check reads the pose's sin β.
  for (double beta : {0.0, kPi, 1e-5}) {
    const EulerAngleTrig<double> trig = EulerAngleTrigOf(0.2, beta, 0.3);
    ExpectJcsSingularity([&] { (void)AngularVelocityMap(beta, trig); }, beta);
  }
}

// The printed Eq. 1.20b reading (docs/model.md §2): ω′y's β̇ cos γ term gets the sign +.
// Independent of the implementation: the expected difference is the term itself,
// w_printed − w_exact = (0, 2 β̇ cos γ, 0), and nothing else changes; its rate term is
// checked by central differences of the printed map itself; ν ↔ q̇ still round-trips.
TEST(AngularVelocityMapPrintedEq1_20b, DiffersFromTheExactMapByTwiceTheBetaDotCosGammaTermInYOnly) {
  const double h = 1e-6;
  int compared = 0;
  ForRandomStates(11, [&](const Vector6d& q, const Vector6d& qd, std::mt19937&) {
    if (std::abs(std::cos(2.0 * q(kGamma)) * std::sin(q(kBeta))) < 0.05) return;  // printed map singular there
    const Vector3d qd_ang = qd.tail<3>();
    const Vector3d w_exact = AngularVelocityT(q, qd);
    const Vector3d rate_exact = AngularVelocityMapRateTimesRate(q(kBeta), q(kGamma), qd_ang);
    Vector3d w_printed, rate_printed, fd;
    Vector6d qd_back;
    {
      ScopedAngularVelocityMapReading printed(AngularVelocityMapReading::kPrintedEq1_20b);
      w_printed = AngularVelocityT(q, qd);
      rate_printed = AngularVelocityMapRateTimesRate(q(kBeta), q(kGamma), qd_ang);
      const Vector6d qp = q + h * qd, qm = q - h * qd;
      fd = (AngularVelocityMap(qp(kBeta), qp(kGamma)) - AngularVelocityMap(qm(kBeta), qm(kGamma))) / (2 * h) * qd_ang;
      qd_back = CoordinateVelocity(q, GeneralizedVelocity(q, qd));
    }
    const double beta_dot = qd(kBeta), gamma = q(kGamma), gamma_dot = qd(kGamma);
    EXPECT_EQ(w_printed.x(), w_exact.x());
    EXPECT_EQ(w_printed.z(), w_exact.z());
    EXPECT_NEAR(w_printed.y() - w_exact.y(), 2.0 * beta_dot * std::cos(gamma), 1e-14);
    EXPECT_EQ(rate_printed.x(), rate_exact.x());
    EXPECT_EQ(rate_printed.z(), rate_exact.z());
    // d/dt (2 β̇ cos γ) at constant β̇: −2 β̇ γ̇ sin γ.
    EXPECT_NEAR(rate_printed.y() - rate_exact.y(), -2.0 * beta_dot * gamma_dot * std::sin(gamma), 1e-13);
    EXPECT_LT((rate_printed - fd).norm(), 1e-8);
    EXPECT_LT((qd_back - qd).norm(), 1e-10);
    ++compared;
  });
  EXPECT_GT(compared, kSamples / 2);
  // The reading ends with its scope: the exact map again.
  const Vector6d q = Vector6d::Zero().eval() + (Vector6d() << 0, 0, 0, 0.3, 1.4, 0.2).finished();
  const Vector6d qd = (Vector6d() << 0, 0, 0, 1.0, 0.5, -0.7).finished();
  EXPECT_NEAR(AngularVelocityT(q, qd).y(), -std::sin(1.4) * std::sin(0.2) * 1.0 - std::cos(0.2) * 0.5, 1e-15);
}

}  // namespace
}  // namespace kneedyn
