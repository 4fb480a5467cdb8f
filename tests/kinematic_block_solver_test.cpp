// Tests of the structured solve of IDA's Newton matrix (formulations/internal/kinematic_block_solver.hpp).
//
// Validates: KinematicBlockLu's solution against Eigen's FullPivLU of the whole matrix on
// random matrices of every reduced size (each fixed-size kernel and the general one, odd
// and even n − 6) with the plain forms' rows F1–F6 (A = −cj I, B = [I 0]) and a general
// 6×6 block, with zero diagonal blocks in S that need pivoting; on the actual Jacobians of
// dae, dae-reduced, dae-ggl and dae-ggl-reduced against SUNDIALS' dense LU; the
// SUNLinearSolver wrapper (x ≠ b and x = b, a singular matrix reported as a recoverable
// LU failure); and a dae run with --linear-solver structured against dense (same events to
// ~rtol). Does not validate: the instruction counts (benchmarks/README.md).
#include <gtest/gtest.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <Eigen/LU>
#include <cmath>
#include <random>
#include <vector>

#include "formulations/internal/dae_system.hpp"
#include "formulations/internal/kinematic_block_solver.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "formulations/run.hpp"
#include "solver/consistent_init.hpp"
#include "solver/units.hpp"
#include "tests/off_rest_state.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;
using test_support::MoveOffRest;

// ‖J x − b‖∞ / (‖J‖∞ ‖x‖∞ + ‖b‖∞): of order ε for a backward-stable solve.
double RelativeResidual(const MatrixXd& J, const VectorXd& x, const VectorXd& b) {
  const double scale = J.cwiseAbs().rowwise().sum().maxCoeff() * x.lpNorm<Eigen::Infinity>() + b.lpNorm<Eigen::Infinity>();
  return (J * x - b).lpNorm<Eigen::Infinity>() / scale;
}

// A Newton matrix of n unknowns shaped like the DAE's: rows F1–F6 = [A | B], `general`
// adds a dense 6×6 perturbation to A = −cj I and fills B's other columns (GGL's μ terms);
// the last `k` columns (N) are zero in the last rows (contact rows do not involve N), so S
// has a zero diagonal block and needs pivoting.
MatrixXd RandomNewtonMatrix(int n, int k, bool general, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double cj = 850.0;
  MatrixXd J = MatrixXd::Zero(n, n);
  for (int i = 0; i < 6; ++i) {
    J(i, i) = -cj;
    J(i, 6 + i) = 1.0;
  }
  if (general) {
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) J(i, j) += 5.0 * u(*rng);
      for (int j = 12; j < n; ++j) J(i, j) = u(*rng);
    }
  }
  for (int i = 6; i < n; ++i) {
    for (int j = 0; j < n; ++j) J(i, j) = (j == i ? 4.0 : 0.0) + u(*rng) * (i < 12 ? 1e3 : 1.0);
  }
  for (int i = n - 2 * k; i < n; ++i) {
    for (int j = n - k; j < n; ++j) J(i, j) = 0.0;
  }
  return J;
}

TEST(KinematicBlockLu, SolvesRandomNewtonMatricesOfEverySize) {
  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (bool general : {false, true}) {
    for (int n = 12; n <= 45; ++n) {
      const int k = std::min(2, (n - 12) / 2);
      const MatrixXd J = RandomNewtonMatrix(n, k, general, &rng);
      VectorXd b(n);
      for (int i = 0; i < n; ++i) b(i) = u(rng);
      KinematicBlockLu lu(n);
      ASSERT_TRUE(lu.Factor(J.data())) << "n = " << n;
      EXPECT_EQ(lu.diagonal(), !general) << "n = " << n;
      VectorXd x = b;
      lu.Solve(x.data());
      const VectorXd reference = J.fullPivLu().solve(b);
      EXPECT_LT(RelativeResidual(J, x, b), 1e-15) << "n = " << n << (general ? " general" : " diagonal");
      EXPECT_LT((x - reference).lpNorm<Eigen::Infinity>(), 1e-11 * reference.lpNorm<Eigen::Infinity>())
          << "n = " << n << (general ? " general" : " diagonal");
    }
  }
}

TEST(KinematicBlockLu, RefusesASingularReducedMatrix) {
  std::mt19937 rng(7);
  MatrixXd J = RandomNewtonMatrix(22, 2, false, &rng);
  J.col(20).setZero();  // N_0 acts nowhere
  KinematicBlockLu lu(22);
  EXPECT_FALSE(lu.Factor(J.data()));
}

struct SystemCase {
  ContactForm form;
  bool ggl;
};

// The matrix IDA factors for `dae`, `dae-reduced`, `dae-ggl`, `dae-ggl-reduced` at a
// consistent start moved off rest (as tests/dae_system_test.cpp), solved by
// KinematicBlockLu and by SUNDIALS' dense LU through the SUNLinearSolver interface.
TEST(KinematicBlockSolver, AgreesWithTheDenseSolverOnTheDaeJacobians) {
  const Scene& scene = ChapterScene();
  for (const SystemCase& c : {SystemCase{ContactForm::kChapter, false}, SystemCase{ContactForm::kClosedForm, false},
                              SystemCase{ContactForm::kChapter, true}, SystemCase{ContactForm::kClosedForm, true}}) {
    ConsistentInitOptions init;
    init.form = c.form;
    MechanicalState s = ConsistentInitialize(scene.model, scene.initial, {0, 1}, init, nullptr);
    std::mt19937 rng(2026);
    MoveOffRest(scene.model, &rng, &s);
    DaeSystem system(scene.model, c.form, ConstraintLevel::kVelocity, c.ggl);
    system.SetPhase(s.active, s.contact, s.ligament_branch);
    const int n = system.size();
    std::vector<double> y(n), yp(n);
    system.InitialValues(s, y.data(), yp.data());
    if (c.ggl) {
      std::uniform_real_distribution<double> u(-1.0, 1.0);
      for (int i = 0; i < 2; ++i) y[system.MuIndex(i)] = 0.3 * u(rng);  // μ ≠ 0: a general 6×6 block
    }
    for (double cj : {30.0, 850.0, 1e5}) {
      SundialsContext ctx;
      SUNMatrix A = SUNDenseMatrix(n, n, ctx);
      ASSERT_TRUE(system.Jacobian(s.t, cj, y.data(), yp.data(), SUNDenseMatrix_Data(A)));
      const MatrixXd J = Eigen::Map<const MatrixXd>(SUNDenseMatrix_Data(A), n, n);
      N_Vector b = NewSerialVector(n, ctx), x = NewSerialVector(n, ctx), x_dense = NewSerialVector(n, ctx);
      std::uniform_real_distribution<double> u(-1.0, 1.0);
      for (int i = 0; i < n; ++i) NvData(b)[i] = u(rng);
      SUNLinearSolver structured = NewKinematicBlockSolver(n, ctx);
      ASSERT_NE(structured, nullptr);
      EXPECT_EQ(SUNLinSolGetType(structured), SUNLINEARSOLVER_DIRECT);
      ASSERT_EQ(SUNLinSolInitialize(structured), SUNLS_SUCCESS);
      ASSERT_EQ(SUNLinSolSetup(structured, A), SUNLS_SUCCESS);
      ASSERT_EQ(SUNLinSolSolve(structured, A, x, b, 0.0), SUNLS_SUCCESS);
      SUNMatrix A_dense = SUNMatClone(A);
      SUNMatCopy(A, A_dense);
      SUNLinearSolver dense = SUNLinSol_Dense(b, A_dense, ctx);
      ASSERT_EQ(SUNLinSolInitialize(dense), SUNLS_SUCCESS);
      ASSERT_EQ(SUNLinSolSetup(dense, A_dense), SUNLS_SUCCESS);
      ASSERT_EQ(SUNLinSolSolve(dense, A_dense, x_dense, b, 0.0), SUNLS_SUCCESS);
      const VectorXd bv = Eigen::Map<const VectorXd>(NvData(b), n);
      const VectorXd xs = Eigen::Map<const VectorXd>(NvData(x), n);
      const VectorXd xd = Eigen::Map<const VectorXd>(NvData(x_dense), n);
      const std::string what = std::string(c.ggl ? "ggl " : "plain ") +
                               (c.form == ContactForm::kChapter ? "chapter" : "closed form") + ", cj = " + std::to_string(cj);
      EXPECT_LT(RelativeResidual(J, xs, bv), 4e-16) << what;
      EXPECT_LT(RelativeResidual(J, xd, bv), 4e-16) << what;  // the reference is as good
      // Unknown by unknown, to the round-off the matrix's condition allows (the forces' columns
      // are ~cj² times the positions' in these units).
      const double cond = J.norm() * J.inverse().norm();
      for (int i = 0; i < n; ++i) {
        EXPECT_NEAR(xs(i), xd(i), 10 * cond * 1e-16 * xd.lpNorm<Eigen::Infinity>()) << what << ", " << system.UnknownName(i);
      }
      // In place (IDA passes the same vector as x and b).
      N_VScale(1.0, b, x);
      ASSERT_EQ(SUNLinSolSolve(structured, A, x, x, 0.0), SUNLS_SUCCESS);
      for (int i = 0; i < n; ++i) EXPECT_EQ(NvData(x)[i], xs(i)) << what;
      // A matrix with a zero pivot is a recoverable failure, as SUNDIALS' dense LU reports it.
      for (int i = 0; i < n; ++i) SUNDenseMatrix_Data(A)[i + static_cast<size_t>(n) * system.NormalIndex(0)] = 0.0;
      EXPECT_EQ(SUNLinSolSetup(structured, A), SUNLS_LUFACT_FAIL) << what;
      SUNLinSolFree(structured);
      SUNLinSolFree(dense);
      SUNMatDestroy(A);
      SUNMatDestroy(A_dense);
      N_VDestroy(b);
      N_VDestroy(x);
      N_VDestroy(x_dense);
    }
  }
}

// The same run with either solver: the trajectories differ at round-off, the events by
// much less than the tolerance's effect on them.
TEST(KinematicBlockSolver, DaeRunGivesTheDenseSolversEvents) {
  for (const char* formulation : {"dae", "dae-ggl"}) {
    RunResult runs[2];
    for (int i = 0; i < 2; ++i) {
      RunSettings settings;
      settings.formulation = formulation;
      settings.options.rtol = 1e-8;
      settings.options.atol = 1e-10;
      settings.options.linear_solver = i == 0 ? LinearSolverKind::kStructured : LinearSolverKind::kDense;
      runs[i] = RunScene(ChapterScene(), settings);
      ASSERT_TRUE(runs[i].completed) << formulation << ": " << runs[i].failure;
    }
    ASSERT_EQ(runs[0].events.size(), runs[1].events.size()) << formulation;
    ASSERT_GE(runs[0].events.size(), 2u) << formulation;
    for (size_t e = 0; e < runs[0].events.size(); ++e) {
      EXPECT_EQ(runs[0].events[e].name, runs[1].events[e].name) << formulation;
      EXPECT_NEAR(runs[0].events[e].time, runs[1].events[e].time, 1e-6) << formulation << " " << runs[0].events[e].name;
      EXPECT_NEAR(runs[0].events[e].flexion, runs[1].events[e].flexion, 1e-6) << formulation << " " << runs[0].events[e].name;
    }
    // Comparable work: neither solver's round-off costs Newton iterations.
    EXPECT_NEAR(static_cast<double>(runs[0].stats.nonlinear_iterations), static_cast<double>(runs[1].stats.nonlinear_iterations),
                0.2 * runs[1].stats.nonlinear_iterations)
        << formulation;
  }
}

}  // namespace
}  // namespace kneedyn
