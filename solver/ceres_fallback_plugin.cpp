// The plugin kneedyn_ceres_fallback.so (solver/ceres_fallback.hpp): Ceres's
// Levenberg–Marquardt on a residual whose values and Jacobian the caller computes (by the
// same forward AD as Ceres's DynamicAutoDiffCostFunction, so the iterates are those of the
// earlier in-process Ceres path bit for bit).
#include <ceres/ceres.h>

#include "solver/ceres_fallback.hpp"
#include "solver/internal/ceres_logging.hpp"

namespace {

class CallbackCost final : public ceres::CostFunction {
 public:
  explicit CallbackCost(const KneedynLeastSquares& p) : p_(p) {
    set_num_residuals(p.num_residuals);
    mutable_parameter_block_sizes()->push_back(p.num_unknowns);
  }
  bool Evaluate(double const* const* x, double* r, double** J) const override {
    return p_.evaluate(p_.user, x[0], r, J ? J[0] : nullptr) != 0;
  }

 private:
  KneedynLeastSquares p_;
};

}  // namespace

extern "C" __attribute__((visibility("default"))) int kneedyn_ceres_fallback_solve_v1(
    const KneedynLeastSquares* p, double* x, int* iterations) {
  try {
    ceres::Problem problem;
    problem.AddResidualBlock(new CallbackCost(*p), nullptr, x);
    kneedyn::QuietCeresLogging();
    ceres::Solver::Options opts;
    opts.linear_solver_type = ceres::DENSE_QR;
    opts.max_num_iterations = p->max_iterations;
    opts.function_tolerance = 1e-30;
    opts.gradient_tolerance = 1e-30;
    opts.parameter_tolerance = 1e-16;
    opts.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(opts, &problem, &summary);
    *iterations = static_cast<int>(summary.iterations.size());
    return 1;
  } catch (...) {  // nothing crosses the C interface
    return 0;
  }
}
