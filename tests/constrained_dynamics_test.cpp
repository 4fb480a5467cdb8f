// Tests of the hidden-constraint solve (solver/constrained_dynamics.hpp).
//
// Validates: the Schur-complement solution (ν̇, N) satisfies the full saddle-point system it
// replaces — M ν̇ − Gᵀ N = Q and G ν̇ = −κ − 2a φ̇ − b² φ, both assembled here from the
// physics functions (MassMatrix, ComputeAppliedWrench/GeneralizedForce,
// ContactConstraintRow, ContactRateTerm) — to round-off, at random states of the chapter
// (sphere on plane) and anatomical (general contact kinematics) scenes, with one and two
// contacts and with Baumgarte gains; q̈ maps back to ν̇; dependent contact rows (two
// identical contacts) are refused with SolverError; the allocation-free overload equals
// the allocating one (a fresh workspace per call) bitwise with ONE workspace and one result
// reused per scene across states and active sets — both contacts, one, the other, none,
// both again, as ede reuses its own — so that state left over from an earlier call (rows,
// sizes, forces of another active set) would show.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "scene/scene.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/error.hpp"
#include "solver/rotation.hpp"
#include "solver/units.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ScenesDir;

// `workspace` and `reused` are shared by every call for the scene (see the header comment).
void CheckSaddlePoint(const Scene& scene, const std::vector<int>& active, BaumgarteGains gains, unsigned seed,
                      ConstrainedDynamicsWorkspace* workspace, ConstrainedAcceleration* reused) {
  const Model& model = scene.model;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d q = scene.initial.q, qd;
  q(kAlpha) += DegToRad(30.0 * (1.0 + u(rng)));
  for (int i = 0; i < 6; ++i) qd(i) = (i < 3 ? 0.05 : 1.5) * u(rng);
  const double t = 0.02 + 0.05 * (1.0 + u(rng));
  const std::vector<signed char> branch = LigamentBranchesAt(model, q, qd);
  const ConstrainedAcceleration a = SolveConstrainedAcceleration(model, t, q, qd, active, gains, &branch);
  ASSERT_EQ(a.normal_force.size(), active.size());

  const Pose pose = PoseFromCoordinates(q);
  const Vector6d nu = GeneralizedVelocity(q, qd);
  Data data(model);
  data.ligament_branch = &branch;
  ComputeAppliedWrench(model, t, pose, &data);
  const Vector6d Q = GeneralizedForce(model, data, Vector3d(nu.tail<3>()));
  Vector6d balance = MassMatrix(model) * a.nu_dot - Q;
  double scale = Q.cwiseAbs().maxCoeff();
  for (size_t r = 0; r < active.size(); ++r) {
    const ContactPair& pair = model.contacts[active[r]];
    const ContactGeometry geo = RequireContactKinematics(pair, pose, "test");
    const Eigen::Matrix<double, 1, 6> G = ContactConstraintRow(pose, geo);
    balance -= G.transpose() * a.normal_force[r];
    scale = std::max(scale, std::abs(a.normal_force[r]));
    const double rhs = -ContactRateTerm(pair, q, qd) - 2.0 * gains.alpha * G.dot(nu) - gains.beta * gains.beta * geo.gap;
    EXPECT_NEAR(G.dot(a.nu_dot), rhs, 1e-12 * (1.0 + std::abs(rhs) + a.nu_dot.cwiseAbs().maxCoeff()))
        << "constraint row " << r;
  }
  EXPECT_LE(balance.cwiseAbs().maxCoeff(), 1e-12 * scale) << "Newton–Euler balance (N, N m)";
  EXPECT_LE((GeneralizedAcceleration(q, qd, a.qdd) - a.nu_dot).cwiseAbs().maxCoeff(),
            1e-12 * (1.0 + a.nu_dot.cwiseAbs().maxCoeff()));

  SolveConstrainedAcceleration(model, t, q, qd, active, gains, &branch, workspace, reused);
  EXPECT_EQ(a.nu_dot, reused->nu_dot) << "reused workspace, " << active.size() << " active contacts";
  EXPECT_EQ(a.qdd, reused->qdd) << "reused workspace, " << active.size() << " active contacts";
  EXPECT_EQ(a.normal_force, reused->normal_force) << "reused workspace, " << active.size() << " active contacts";
}

TEST(SolveConstrainedAcceleration, SatisfiesTheSaddlePointSystem) {
  const Scene& chapter = test_support::ChapterScene();
  const Scene anatomical = LoadScene(ScenesDir() + "/anatomical_surfaces.yaml");
  // One workspace and one result per scene for the whole loop: each seed runs both
  // contacts, one, the other, none, and the next seed both again.
  ConstrainedDynamicsWorkspace chapter_ws(chapter.model), anatomical_ws(anatomical.model);
  ConstrainedAcceleration chapter_out, anatomical_out;
  for (unsigned seed = 1; seed <= 5; ++seed) {
    SCOPED_TRACE(seed);
    CheckSaddlePoint(chapter, {0, 1}, {}, seed, &chapter_ws, &chapter_out);
    CheckSaddlePoint(chapter, {1}, {}, seed, &chapter_ws, &chapter_out);
    CheckSaddlePoint(chapter, {0, 1}, {20.0, 20.0}, seed, &chapter_ws, &chapter_out);
    CheckSaddlePoint(chapter, {0}, {}, seed, &chapter_ws, &chapter_out);
    CheckSaddlePoint(chapter, {}, {}, seed, &chapter_ws, &chapter_out);
    CheckSaddlePoint(anatomical, {0, 1}, {}, seed, &anatomical_ws, &anatomical_out);
    CheckSaddlePoint(anatomical, {0}, {5.0, 7.0}, seed, &anatomical_ws, &anatomical_out);
    CheckSaddlePoint(anatomical, {1}, {}, seed, &anatomical_ws, &anatomical_out);
    CheckSaddlePoint(anatomical, {}, {}, seed, &anatomical_ws, &anatomical_out);
  }
}

// The impact pulse acts at the centre of mass along direction_T, which turns with the tibia
// (docs/model.md §7): on a free tibia at rest (no contact, ligament or gravity) the centre of
// mass accelerates by F(t) R_FT d_T / m, F(t) = A sin(π t / t0) for a half-sine, and the
// pulse exerts no moment. The pose is turned about all three axes so that T ≠ F.
TEST(SolveConstrainedAcceleration, PulseActsAtTheCentreOfMassAlongItsTibialDirection) {
  Model model = LoadScene(ScenesDir() + "/chapter_impact.yaml").model;
  model.ligaments.clear();
  model.gravity_F = Vector3d::Zero();
  model.pulse.shape = PulseShape::kHalfSine;
  model.pulse.amplitude = 100.0;
  model.pulse.duration = 0.1;
  model.pulse.direction_T = Vector3d(0.3, -0.9, 0.2).normalized();
  Vector6d q;
  q << 0.001, -0.04, -0.23, 0.7, kPi / 2 + 0.15, -0.25;
  const Vector6d qd = Vector6d::Zero();
  const double t = 0.02;
  const ConstrainedAcceleration a = SolveConstrainedAcceleration(model, t, q, qd, {});
  const Matrix3d R_FT = RotationFT(q(kAlpha), q(kBeta), q(kGamma));
  const Vector3d expected = 100.0 * std::sin(kPi * t / 0.1) * R_FT * model.pulse.direction_T / model.mass;
  EXPECT_LT((a.qdd.head<3>() - expected).norm(), 1e-12 * expected.norm())
      << a.qdd.head<3>().transpose() << " vs " << expected.transpose();
  EXPECT_LT(a.qdd.tail<3>().norm(), 1e-12) << "a force at the centre of mass turns nothing";
  EXPECT_GT((R_FT * model.pulse.direction_T - model.pulse.direction_T).norm(), 0.1) << "the pose must tell T from F";
}

TEST(SolveConstrainedAcceleration, RefusesDependentContactRows) {
  Scene scene = test_support::ChapterScene();
  scene.model.contacts[1] = scene.model.contacts[0];  // the same pair twice: equal rows
  EXPECT_THROW(SolveConstrainedAcceleration(scene.model, 0.0, scene.initial.q, scene.initial.qd, {0, 1}),
               SolverError);
}

// SolveSmallFullPivLu replaces Eigen's FullPivLU in the Schur-complement solve and claims
// its operations in its order: the solution must equal FullPivLU's bit for bit (the second
// engine), and the rank by the same rule, for every size the solve allows, on symmetric
// positive definite (the Schur complement's case), general, ill-conditioned, with zero
// entries (the triangular solves' skips) and singular matrices.
TEST(SolveSmallFullPivLu, EqualsEigenFullPivLuBitwise) {
  using Matrix = ConstrainedDynamicsWorkspace::Matrix;
  using Vector = ConstrainedDynamicsWorkspace::Vector;
  std::mt19937 rng(20261202);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int compared = 0, singular = 0;
  for (int k = 1; k <= kMaxConstrainedContacts; ++k) {
    for (int trial = 0; trial < 200; ++trial) {
      Matrix S(k, k);
      for (int i = 0; i < k * k; ++i) S.data()[i] = u(rng) * std::pow(10.0, 6.0 * u(rng));
      const int kind = trial % 5;
      if (kind == 0) S = (S * S.transpose()).eval();  // SPD
      if (kind == 1) S(k - 1, 0) = S(0, k - 1) = 0.0;
      if (kind == 2 && k > 1) S.col(k - 1) = S.col(0) * 3.0;  // rank k − 1
      if (kind == 3 && k > 1) S.col(k - 1) = S.col(0) * (1.0 + 1e-15);  // nearly dependent
      Vector b(k);
      for (int i = 0; i < k; ++i) b(i) = trial % 7 == 0 && i == 0 ? 0.0 : u(rng);
      const Eigen::FullPivLU<Matrix> lu(S);
      Vector x = Vector::Constant(k, -7.0);
      const int rank = SolveSmallFullPivLu(k, S.data(), b.data(), x.data());
      ASSERT_EQ(rank, lu.rank()) << "k = " << k << ", trial " << trial;
      if (rank < k) {
        ++singular;
        continue;
      }
      const Vector expected = lu.solve(b);
      for (int i = 0; i < k; ++i) {
        ASSERT_EQ(std::memcmp(&x(i), &expected(i), sizeof(double)), 0)
            << "k = " << k << ", trial " << trial << ", x(" << i << ") = " << x(i) << " vs " << expected(i);
      }
      ++compared;
    }
  }
  EXPECT_GT(compared, 800);
  EXPECT_GT(singular, 100);
  const Matrix zero = Matrix::Zero(2, 2);
  const double b[2] = {1.0, 2.0};
  double x[2];
  EXPECT_EQ(SolveSmallFullPivLu(2, zero.data(), b, x), 0);
  EXPECT_THROW(SolveSmallFullPivLu(kMaxConstrainedContacts + 1, zero.data(), b, x), SolverError);
}

// SolveSchurComplement (closed-form inverse for k ≤ 2) against Eigen's FullPivLU, the second
// engine: on well-conditioned symmetric positive definite matrices (the Schur complement's
// case) the solutions agree to round-off (1e-13 relative); on exactly dependent columns and on
// zero matrices both report the same rank < k.
TEST(SolveSchurComplement, AgreesWithFullPivLu) {
  using Matrix = ConstrainedDynamicsWorkspace::Matrix;
  using Vector = ConstrainedDynamicsWorkspace::Vector;
  std::mt19937 rng(20261203);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int compared = 0, singular = 0;
  for (int k = 1; k <= kMaxConstrainedContacts; ++k) {
    for (int trial = 0; trial < 200; ++trial) {
      Matrix A(k, k);
      for (int i = 0; i < k * k; ++i) A.data()[i] = u(rng);
      const double scale = std::pow(10.0, 6.0 * u(rng));  // N⁻¹ m⁻¹ ... of any magnitude
      Matrix S = scale * (A * A.transpose() + Matrix::Identity(k, k));
      const bool dependent = trial % 4 == 0;
      if (dependent) S = Matrix::Zero(k, k);
      if (dependent && k > 1) {
        S.col(0).setConstant(scale);
        S.col(k - 1) = S.col(0) * 3.0;  // rank 1 (k = 2) or ≤ k − 1
      }
      Vector b(k);
      for (int i = 0; i < k; ++i) b(i) = u(rng);
      const Eigen::FullPivLU<Matrix> lu(S);
      Vector x = Vector::Constant(k, -7.0);
      const int rank = SolveSchurComplement(k, S.data(), b.data(), x.data());
      ASSERT_EQ(rank, lu.rank()) << "k = " << k << ", trial " << trial;
      if (rank < k) {
        ASSERT_TRUE(dependent) << "k = " << k << ", trial " << trial;
        ++singular;
        continue;
      }
      const Vector expected = lu.solve(b);
      EXPECT_LE((x - expected).norm(), 1e-13 * expected.norm()) << "k = " << k << ", trial " << trial;
      ++compared;
    }
  }
  EXPECT_GT(compared, 1000);
  EXPECT_GT(singular, 300);
}

}  // namespace
}  // namespace kneedyn
