// Tests of kneedyn's SUNDIALS kernels (formulations/internal/sundials_kernels.hpp).
//
// Validates: every vector operation kneedyn installs gives bitwise the result of the
// library's own serial operation (called through the same generic N_V* entry points on a
// pristine NVECTOR_SERIAL vector, so the library's fallbacks for the fused and
// vector-array operations are what is compared), for random data, the special
// coefficients the library branches on (±1, 0, a = ±b) and aliased arguments; the dense LU
// gives bitwise the factors, solutions and singular-pivot flag of SUNLinSol_Dense; whole
// runs of IDA, CVODE (BDF with the dense solver, Adams) and ARKODE formulations give
// bitwise the same trajectories, event times and counters with either set of kernels.
// Does not validate: speed (benchmarks/micro_benchmarks.cpp, instruction counts).
#include <gtest/gtest.h>

#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "formulations/run.hpp"
#include "formulations/internal/sundials_kernels.hpp"
#include "formulations/internal/sundials_util.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Two families of vectors with equal contents: `lib` with the library's operations,
// `ours` with kneedyn's kernels.
struct Pair {
  std::vector<N_Vector> lib, ours;
};

class VectorKernels : public ::testing::Test {
 protected:
  static constexpr int kVectors = 6;
  void SetUp() override { rng_.seed(99); }
  void TearDown() override {
    for (Pair* p : {&a_}) {
      for (N_Vector v : p->lib) N_VDestroy(v);
      for (N_Vector v : p->ours) N_VDestroy(v);
    }
  }
  // Random contents (some exact zeros and ±1 so the branches on values are exercised).
  void Fill(int n) {
    std::uniform_real_distribution<double> u(-3.0, 3.0);
    for (int k = 0; k < kVectors; ++k) {
      N_Vector l = N_VNew_Serial(n, ctx_);
      N_Vector o = N_VNew_Serial(n, ctx_);
      InstallVectorKernels(o);
      for (int i = 0; i < n; ++i) {
        double x = u(rng_);
        if (i % 7 == 3) x = 0.0;
        if (i % 11 == 5) x = k % 2 ? 1.0 : -1.0;
        NV_Ith_S(l, i) = NV_Ith_S(o, i) = x;
      }
      a_.lib.push_back(l);
      a_.ours.push_back(o);
    }
  }
  void ExpectSame(const char* what) {
    for (int k = 0; k < kVectors; ++k) {
      for (sunindextype i = 0; i < NV_LENGTH_S(a_.lib[k]); ++i) {
        EXPECT_TRUE(SameBits(NV_Ith_S(a_.lib[k], i), NV_Ith_S(a_.ours[k], i)))
            << what << ": vector " << k << "[" << i << "] " << NV_Ith_S(a_.lib[k], i) << " vs "
            << NV_Ith_S(a_.ours[k], i);
      }
    }
  }
  // Runs `op` on both families and compares all vectors and the returned value bitwise.
  void Check(const char* what, const std::function<double(std::vector<N_Vector>&)>& op) {
    const double r_lib = op(a_.lib);
    const double r_ours = op(a_.ours);
    EXPECT_TRUE(SameBits(r_lib, r_ours)) << what << ": returned " << r_lib << " vs " << r_ours;
    ExpectSame(what);
    // Re-align after a mismatch so that every operation is judged on its own.
    for (int k = 0; k < kVectors; ++k) {
      for (sunindextype i = 0; i < NV_LENGTH_S(a_.lib[k]); ++i) NV_Ith_S(a_.ours[k], i) = NV_Ith_S(a_.lib[k], i);
    }
  }
  SundialsContext ctx_;
  std::mt19937 rng_;
  Pair a_;
};

TEST_F(VectorKernels, EveryOperationIsBitwiseTheLibrarys) {
  for (int n : {1, 7, 22}) {
    TearDown();
    a_ = Pair();
    Fill(n);
    const double coefficients[] = {1.0, -1.0, 0.0, 2.5, -2.5, 0.3};
    for (double a : coefficients) {
      for (double b : coefficients) {
        const std::string tag = " a = " + std::to_string(a) + ", b = " + std::to_string(b);
        Check(("LinearSum" + tag).c_str(), [&](auto& v) { N_VLinearSum(a, v[0], b, v[1], v[2]); return 0.0; });
        Check(("LinearSum z = x" + tag).c_str(), [&](auto& v) { N_VLinearSum(a, v[3], b, v[1], v[3]); return 0.0; });
        Check(("LinearSum z = y" + tag).c_str(), [&](auto& v) { N_VLinearSum(a, v[0], b, v[4], v[4]); return 0.0; });
        Check(("LinearSumVectorArray" + tag).c_str(), [&](auto& v) {
          N_Vector X[2] = {v[0], v[1]}, Y[2] = {v[2], v[3]}, Z[2] = {v[4], v[5]};
          return static_cast<double>(N_VLinearSumVectorArray(2, a, X, b, Y, Z));
        });
      }
      Check("Scale", [&](auto& v) { N_VScale(a, v[0], v[5]); return 0.0; });
      Check("Scale in place", [&](auto& v) { N_VScale(a, v[5], v[5]); return 0.0; });
      Check("Const", [&](auto& v) { N_VConst(a, v[2]); return 0.0; });
      Check("AddConst", [&](auto& v) { N_VAddConst(v[0], a, v[3]); return 0.0; });
      Check("Compare", [&](auto& v) { N_VCompare(std::abs(a), v[1], v[4]); return 0.0; });
      double c3[3] = {a, 0.7, -1.0};
      Check("LinearCombination", [&](auto& v) {
        N_Vector X[3] = {v[0], v[1], v[2]};
        return static_cast<double>(N_VLinearCombination(3, c3, X, v[3]));
      });
      Check("LinearCombination z = X0", [&](auto& v) {
        N_Vector X[3] = {v[3], v[1], v[2]};
        return static_cast<double>(N_VLinearCombination(3, c3, X, v[3]));
      });
      Check("ScaleAddMulti", [&](auto& v) {
        N_Vector Y[2] = {v[1], v[2]}, Z[2] = {v[3], v[4]};
        double c2[2] = {a, 1.0};
        return static_cast<double>(N_VScaleAddMulti(2, c2, v[0], Y, Z));
      });
      Check("ScaleAddMulti Y = Z", [&](auto& v) {
        N_Vector Y[2] = {v[1], v[2]};
        double c2[2] = {a, -1.0};
        return static_cast<double>(N_VScaleAddMulti(2, c2, v[0], Y, Y));
      });
      Check("ScaleVectorArray", [&](auto& v) {
        N_Vector X[2] = {v[0], v[1]}, Z[2] = {v[2], v[3]};
        double c2[2] = {a, 1.0};
        return static_cast<double>(N_VScaleVectorArray(2, c2, X, Z));
      });
      Check("ConstVectorArray", [&](auto& v) {
        N_Vector Z[2] = {v[4], v[5]};
        return static_cast<double>(N_VConstVectorArray(2, a, Z));
      });
      Check("ScaleAddMultiVectorArray", [&](auto& v) {
        N_Vector X[2] = {v[0], v[1]};
        N_Vector Y0[2] = {v[2], v[3]}, Y1[2] = {v[3], v[2]};
        N_Vector Z0[2] = {v[4], v[5]}, Z1[2] = {v[5], v[4]};
        N_Vector* Y[2] = {Y0, Y1};
        N_Vector* Z[2] = {Z0, Z1};
        double c2[2] = {a, 0.25};
        return static_cast<double>(N_VScaleAddMultiVectorArray(2, 2, c2, X, Y, Z));
      });
      Check("LinearCombinationVectorArray", [&](auto& v) {
        N_Vector X0[2] = {v[0], v[1]}, X1[2] = {v[1], v[2]}, X2[2] = {v[2], v[0]};
        N_Vector* X[3] = {X0, X1, X2};
        N_Vector Z[2] = {v[4], v[5]};
        return static_cast<double>(N_VLinearCombinationVectorArray(2, 3, c3, X, Z));
      });
    }
    Check("Prod", [&](auto& v) { N_VProd(v[0], v[1], v[2]); return 0.0; });
    Check("Div", [&](auto& v) { N_VDiv(v[0], v[5], v[3]); return 0.0; });
    Check("Abs", [&](auto& v) { N_VAbs(v[0], v[4]); return 0.0; });
    Check("Inv", [&](auto& v) { N_VInv(v[5], v[2]); return 0.0; });
    Check("DotProd", [&](auto& v) { return N_VDotProd(v[0], v[1]); });
    Check("MaxNorm", [&](auto& v) { return N_VMaxNorm(v[2]); });
    Check("WrmsNorm", [&](auto& v) { return N_VWrmsNorm(v[0], v[1]); });
    Check("WrmsNormMask", [&](auto& v) { return N_VWrmsNormMask(v[0], v[1], v[2]); });
    Check("Min", [&](auto& v) { return N_VMin(v[3]); });
    Check("WL2Norm", [&](auto& v) { return N_VWL2Norm(v[0], v[1]); });
    Check("L1Norm", [&](auto& v) { return N_VL1Norm(v[4]); });
    Check("InvTest", [&](auto& v) { return static_cast<double>(N_VInvTest(v[0], v[5])); });
    Check("ConstrMask", [&](auto& v) {
      for (int i = 0; i < NV_LENGTH_S(v[1]); ++i) NV_Ith_S(v[1], i) = static_cast<double>(i % 5 - 2);  // codes −2…2
      return static_cast<double>(N_VConstrMask(v[1], v[0], v[2]));
    });
    Check("MinQuotient", [&](auto& v) { return N_VMinQuotient(v[0], v[3]); });
    Check("DotProdMulti", [&](auto& v) {
      N_Vector Y[3] = {v[1], v[2], v[3]};
      double d[3];
      N_VDotProdMulti(3, v[0], Y, d);
      return d[0] + 2.0 * d[1] + 3.0 * d[2];
    });
    Check("WrmsNormVectorArray", [&](auto& v) {
      N_Vector X[2] = {v[0], v[1]}, W[2] = {v[2], v[3]};
      double r[2];
      N_VWrmsNormVectorArray(2, X, W, r);
      return r[0] + 2.0 * r[1];
    });
    Check("WrmsNormMaskVectorArray", [&](auto& v) {
      N_Vector X[2] = {v[0], v[1]}, W[2] = {v[2], v[3]};
      double r[2];
      N_VWrmsNormMaskVectorArray(2, X, W, v[4], r);
      return r[0] + 2.0 * r[1];
    });
  }
}

// Clones (every internal vector of an integrator) carry the kernels.
TEST_F(VectorKernels, ClonesKeepTheKernels) {
  SetKneedynSundialsKernels(true);
  N_Vector v = NewSerialVector(5, ctx_);
  N_Vector w = N_VClone(v);
  EXPECT_EQ(w->ops->nvlinearsum, v->ops->nvlinearsum);
  EXPECT_NE(w->ops->nvlinearsum, &N_VLinearSum_Serial);
  N_VDestroy(w);
  N_VDestroy(v);
}

TEST(DenseLinearSolver, BitwiseTheLibrarysFactorsAndSolutions) {
  SundialsContext ctx;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int n : {1, 2, 12, 22, 24}) {
    for (bool singular : {false, true}) {
      SUNMatrix A_lib = SUNDenseMatrix(n, n, ctx), A_ours = SUNDenseMatrix(n, n, ctx);
      N_Vector y = N_VNew_Serial(n, ctx), b = N_VNew_Serial(n, ctx);
      N_Vector x_lib = N_VNew_Serial(n, ctx), x_ours = N_VNew_Serial(n, ctx);
      for (int i = 0; i < n * n; ++i) {
        double v = u(rng);
        if (i % 5 == 2) v = 0.0;  // the a_kj = 0 skip
        SUNDenseMatrix_Data(A_lib)[i] = SUNDenseMatrix_Data(A_ours)[i] = v;
      }
      if (singular) {  // a zero middle column: the pivot of that step is exactly zero
        const int j = n / 2;
        for (int i = 0; i < n; ++i) SUNDenseMatrix_Data(A_lib)[j * n + i] = SUNDenseMatrix_Data(A_ours)[j * n + i] = 0.0;
      }
      for (int i = 0; i < n; ++i) NV_Ith_S(b, i) = u(rng);
      SetKneedynSundialsKernels(false);
      SUNLinearSolver S_lib = NewDenseLinearSolver(y, A_lib, ctx);
      SetKneedynSundialsKernels(true);
      SUNLinearSolver S_ours = NewDenseLinearSolver(y, A_ours, ctx);
      ASSERT_EQ(SUNLinSolGetID(S_lib), SUNLINEARSOLVER_DENSE);
      ASSERT_EQ(SUNLinSolGetID(S_ours), SUNLINEARSOLVER_CUSTOM);
      SUNLinSolInitialize(S_lib);
      SUNLinSolInitialize(S_ours);
      const int f_lib = SUNLinSolSetup(S_lib, A_lib), f_ours = SUNLinSolSetup(S_ours, A_ours);
      EXPECT_EQ(f_lib, f_ours) << "n = " << n;
      EXPECT_EQ(SUNLinSolLastFlag(S_lib), SUNLinSolLastFlag(S_ours)) << "n = " << n;
      if (singular) {
        EXPECT_EQ(f_ours, SUNLS_LUFACT_FAIL);
      }
      if (f_lib == 0) {
        for (int i = 0; i < n * n; ++i) {
          ASSERT_TRUE(SameBits(SUNDenseMatrix_Data(A_lib)[i], SUNDenseMatrix_Data(A_ours)[i])) << "n = " << n << ", factor entry " << i;
        }
        SUNLinSolSolve(S_lib, A_lib, x_lib, b, 0.0);
        SUNLinSolSolve(S_ours, A_ours, x_ours, b, 0.0);
        for (int i = 0; i < n; ++i) {
          ASSERT_TRUE(SameBits(NV_Ith_S(x_lib, i), NV_Ith_S(x_ours, i))) << "n = " << n << ", x[" << i << "]";
        }
        SUNLinSolSolve(S_ours, A_ours, b, b, 0.0);  // in place, as IDA may call it
        for (int i = 0; i < n; ++i) ASSERT_TRUE(SameBits(NV_Ith_S(x_lib, i), NV_Ith_S(b, i)));
      }
      SUNLinSolFree(S_lib);
      SUNLinSolFree(S_ours);
      SUNMatDestroy(A_lib);
      SUNMatDestroy(A_ours);
      for (N_Vector v : {y, b, x_lib, x_ours}) N_VDestroy(v);
    }
  }
}

// Whole runs: the kernels change no bit of what a formulation computes.
struct RunCase {
  const char* formulation;
  const char* integrator;
};
class KernelsInWholeRuns : public ::testing::TestWithParam<RunCase> {};

TEST_P(KernelsInWholeRuns, TrajectoriesAndCountersAreBitwiseEqual) {
  const Scene& scene = test_support::ChapterScene();
  RunSettings settings;
  settings.formulation = GetParam().formulation;
  settings.options.integrator = IntegratorOption(GetParam().integrator);
  settings.options.rtol = 1e-7;
  settings.options.atol = 1e-9;
  SetKneedynSundialsKernels(false);
  const RunResult lib = RunScene(scene, settings);
  SetKneedynSundialsKernels(true);
  const RunResult ours = RunScene(scene, settings);
  ASSERT_TRUE(lib.completed) << lib.failure;
  ASSERT_TRUE(ours.completed) << ours.failure;
  ASSERT_EQ(lib.samples.size(), ours.samples.size());
  for (size_t k = 0; k < lib.samples.size(); ++k) {
    ASSERT_TRUE(SameBits(lib.samples[k].t, ours.samples[k].t)) << "sample " << k;
    for (int i = 0; i < 6; ++i) {
      ASSERT_TRUE(SameBits(lib.samples[k].q(i), ours.samples[k].q(i))) << "sample " << k << " q" << i;
      ASSERT_TRUE(SameBits(lib.samples[k].qd(i), ours.samples[k].qd(i))) << "sample " << k << " qd" << i;
    }
  }
  EXPECT_EQ(lib.stats.steps, ours.stats.steps);
  EXPECT_EQ(lib.stats.residual_evaluations, ours.stats.residual_evaluations);
  EXPECT_EQ(lib.stats.jacobian_evaluations, ours.stats.jacobian_evaluations);
  EXPECT_EQ(lib.stats.nonlinear_iterations, ours.stats.nonlinear_iterations);
  ASSERT_EQ(lib.events.size(), ours.events.size());
  for (size_t e = 0; e < lib.events.size(); ++e) EXPECT_TRUE(SameBits(lib.events[e].time, ours.events[e].time));
}

INSTANTIATE_TEST_SUITE_P(Integrators, KernelsInWholeRuns,
                         ::testing::Values(RunCase{"dae", ""}, RunCase{"dae-ggl-reduced", ""},
                                           RunCase{"ede", "cvode-bdf"}, RunCase{"ede", "cvode-adams"},
                                           RunCase{"mde", "dopri5"}),
                         [](const ::testing::TestParamInfo<RunCase>& info) {
                           std::string n = std::string(info.param.formulation) + "_" + info.param.integrator;
                           for (char& c : n) {
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           }
                           return n;
                         });

}  // namespace
}  // namespace kneedyn
