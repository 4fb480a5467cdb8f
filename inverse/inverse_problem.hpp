// The bounded inverse problem: which change of the chapter's uncertain continuous quantities
// (Table 1.1 insertion coordinates, Table 1.2 stiffnesses, Table 1.3 extension ratios, i.e.
// the reference strains e − 1) reaches the chapter's quantitative statements, and how large
// it is against the precision the chapter prints them with.
//
// Unknowns: x_i = Δp_i / b_i, the change of parameter i divided by its bound b_i (half a unit
// of the last printed digit, inverse/inverse_problem.yaml says why per quantity). "Smallest
// change" is the smallest ‖x‖₂; |x_i| ≤ 1 is within the printed precision.
// Statements (the same file): a value of one run of the scene, with its pulse duration set
// per statement (Figs. 1.7–1.25 are drawn for A = 100 N, t0 = 0.05 … 0.2 s):
//   outcome            a column of `kneedyn sensitivity` (lift-off angle, peak ligament force)
//   crossing           flexion (deg) of the first + → − crossing of a coordinate's deviation
//                      from its reference (β − 90°) after 1° of flexion (Fig. 1.7)
//   peak_location      flexion (deg) of the maximum of sign × coordinate in a flexion window
//   rate_peak_location the same for the coordinate's time derivative (Figs. 1.11–1.15)
// Each statement contributes r = (value − target) / tolerance.
// Gradients: every value is a function of one IDAS/CVODES sensitivity run
// (sensitivity/forward_sensitivity.hpp): outcomes take its derivatives directly; the
// trajectory statements are closed-form functions of the output samples (q_k, ∂q_k/∂p at
// fixed times 1 ms apart: linear interpolation of a crossing, the vertex of the parabola
// through the three samples around a discrete maximum, rates as central differences in
// time), differentiated exactly with Ceres Jets through those samples. No finite
// difference in p is taken.
#pragma once

#include <string>
#include <vector>

#include "scene/scene.hpp"
#include "sensitivity/forward_sensitivity.hpp"

namespace kneedyn::inverse {

struct UncertainParameter {
  std::string name;    // a `kneedyn sensitivity` parameter name (ACL_anterior.femoral_x)
  double bound = 0.0;  // b_i, in the parameter's units (mm, N/mm, N/mm², 1)
  std::string reason;  // why b_i is what it is
};

enum class StatementKind { kOutcome, kCrossing, kPeakLocation, kRatePeakLocation };

struct Statement {
  std::string id;     // unique (C1, K6_short)
  std::string claim;  // the claim id of reports/claims.yaml it belongs to
  StatementKind kind = StatementKind::kOutcome;
  std::string outcome;       // kOutcome: sensitivity outcome column
  int coordinate = -1;       // trajectory kinds: q index (solver/pose.hpp CoordinateIndex)
  double offset = 0.0;       // kCrossing: the coordinate's reference value (SI: rad or m)
  double sign = 1.0;         // peak kinds: +1 maximum, −1 minimum
  double window_lo_deg = 0.0, window_hi_deg = 90.0;  // peak kinds: flexion window
  double duration_s = 0.0;   // pulse duration of the run; 0 keeps the scene's
  double target = 0.0;       // chapter value (deg or N)
  double tolerance = 1.0;    // residual scale (deg or N)
  std::string half;          // "A" or "B": the leave-some-out split
  std::string reason;
};

struct InverseSpec {
  std::vector<UncertainParameter> parameters;
  std::vector<Statement> statements;
  double reach_fraction = 0.1;  // reached: |value − target| ≤ reach_fraction × tolerance
};

// Reads the parameter/bounds and statements file; InputError naming the field and value.
InverseSpec LoadInverseSpec(const std::string& path);

// Values of the statements (and their derivatives in x) at a normalized change x.
class StatementModel {
 public:
  // Resolves the parameter names against `scene` (InputError for an unknown name).
  StatementModel(Scene scene, InverseSpec spec, sensitivity::SensitivityOptions options);

  int num_parameters() const { return static_cast<int>(spec_.parameters.size()); }
  const InverseSpec& spec() const { return spec_; }
  const Scene& scene() const { return scene_; }
  // Parameter values p = nominal + x ∘ b (the units of the sensitivity parameters).
  std::vector<double> Values(const std::vector<double>& x) const;
  const std::vector<double>& nominal() const { return nominal_; }

  struct Evaluation {
    std::vector<double> value;                   // per requested statement (deg or N)
    std::vector<std::vector<double>> jacobian;   // [statement][parameter] d value / d x; empty without
  };
  // One sensitivity run per distinct pulse duration of the requested statements. Throws
  // SolverError when a run fails or a statement is not reached (no lift-off, no crossing).
  Evaluation Evaluate(const std::vector<double>& x, const std::vector<int>& statements, bool derivatives) const;
  // Restricts the unknowns to `free` (indices into spec().parameters); the others stay at 0.
  void SetFree(const std::vector<int>& free) { free_ = free; }
  const std::vector<int>& free() const { return free_; }
  mutable long runs = 0;

 private:
  Scene scene_;
  InverseSpec spec_;
  sensitivity::SensitivityOptions options_;
  std::vector<ensembles::ParameterSpec> parameters_;
  std::vector<double> nominal_;
  std::vector<int> free_;
};

struct FitOptions {
  // Penalty weights w of the statement residuals, one stage each, warm-started: each stage
  // solves min ‖x‖² + w² Σ (r_k + μ_k)² with Ceres; with w ≫ ‖x‖ the result approaches
  // min ‖x‖ subject to r = 0. The end point of every stage is evaluated and the best kept
  // (all statements reached with the smallest ‖x‖, else the smallest largest |r|): the
  // statements are rough functions of x (ligament branch switches, the published law's
  // jump), and a large w can end worse than a smaller one. multiplier_updates > 0 adds the
  // augmented Lagrangian's μ_k ← μ_k + r_k per stage (off by default: measured on C1 with
  // 10-iteration stages, the updates overshot and ended at 53.8° with ‖x‖ = 31, where the
  // plain continuation 30, 300, 3000 reached 66.8° with ‖x‖ = 22.5).
  std::vector<double> weights = {30.0, 300.0, 3000.0};
  int multiplier_updates = 0;
  double regularization = 1.0;  // 0: plain least squares on the statements (recovery tests)
  double box = 0.0;             // > 0: |x_i| ≤ box (1: within the printed precision)
  int max_iterations = 8;       // per stage
  // Levenberg–Marquardt's trust region: false (Ceres' default) scales it by diag(JᵀJ);
  // true makes it a ball in x. Measured on C1 (15 iterations at w = 1000): the scaled
  // region reached 66° with ‖x‖ = 49, the ball got to 61.8° (‖x‖ = 40).
  bool isotropic = false;
};

struct FitResult {
  std::vector<double> x;        // over all spec parameters (0 where not free)
  std::vector<double> value;    // the fitted statements at x
  std::vector<double> residual; // (value − target) / tolerance
  double norm = 0.0;            // ‖x‖₂
  double max_abs = 0.0;         // max |x_i|
  int iterations = 0;
  long runs = 0;
  bool converged = false;
  std::string report;           // Ceres brief reports of the stages
};

// Fits the statements `fit` (indices into spec().statements) from x = 0.
FitResult Fit(const StatementModel& model, const std::vector<int>& fit, const FitOptions& options);

}  // namespace kneedyn::inverse
