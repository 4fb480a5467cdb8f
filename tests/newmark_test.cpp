// Tests of `newmark` and `newmark-reduced` (formulations/newmark.cpp).
//
// Validates: second-order convergence against an exact solution (torque-free regular
// precession of the axisymmetric tibia under gravity); agreement of both contact forms
// with the independent `dae` formulation on the chapter's scene; that a Newton failure
// halves the step and ends in a SolverError naming t and h.
// Does not validate: accuracy of the normal forces between events (the undamped Newmark
// rule leaves an O(h) period-2 oscillation in N on position-level constraints), speed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "formulations/internal/newmark_testing.hpp"
#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

// Free tibia (no contacts, no ligaments): gravity translates it (constant acceleration,
// which Newmark integrates exactly) while it spins torque-free. Its principal moments are
// axisymmetric (I1 = I2 = 0.0672, I3 = 0.005334 kg m², chapter_knee.yaml), so the motion
// is a regular precession with the closed form
//   R_FT(t) = Rot(L̂, ω_p t) R_FT(0) Rot(z′, ψ̇ t),  ω_p = |L| / I1,  ψ̇ = −(I3 − I1) ω_z / I1,
// L = R_FT(0) I ω_T(0) (check: Ṙ = R [ω_p RᵀL̂ + ψ̇ z′]× and R I ω_T = L for all t).
// The JCS angles of this motion are non-polynomial in t, so Newmark is not exact.
constexpr char kFreeTibia[] = R"(
name: free_tibia
description: torque-free precession with gravity
parameter_set: ../chapter_knee.yaml
ligaments: none
contacts: []
gravity: {enabled: true}
pulse: {shape: none}
initial_state:
  pose: reference
  velocities: {x0_mm_s: 10.0, alpha_deg_s: 200.0, beta_deg_s: 60.0, gamma_deg_s: 400.0}
end: {time_s: 0.2}
output: {interval_s: 0.02}
)";

Scene FreeTibiaScene() {
  return ParseScene(kFreeTibia, "free_tibia (inline)", ReferenceDataDir() + "/scenes");
}

// Max-abs error of the final pose against the closed form.
double FinalPoseError(const Scene& scene, const MechanicalState& end) {
  const Model& model = scene.model;
  const Vector6d& q0 = scene.initial.q;
  const Vector6d& qd0 = scene.initial.qd;
  const double t = end.t;
  const Matrix3d R0 = RotationFT(q0(kAlpha), q0(kBeta), q0(kGamma));
  const Vector3d w0_T = AngularVelocityT(q0, qd0);
  const double I1 = model.inertia_T.x(), I3 = model.inertia_T.z();
  const Vector3d L_F = R0 * model.inertia_T.cwiseProduct(w0_T);
  const double omega_p = L_F.norm() / I1;
  const double psi_dot = -(I3 - I1) * w0_T.z() / I1;
  const Matrix3d R_exact = Eigen::AngleAxisd(omega_p * t, L_F.normalized()).toRotationMatrix() * R0 *
                           Eigen::AngleAxisd(psi_dot * t, Vector3d::UnitZ()).toRotationMatrix();
  const Vector3d p_exact = q0.head<3>() + qd0.head<3>() * t + 0.5 * model.gravity_F * t * t;
  const Matrix3d R_num = RotationFT(end.q(kAlpha), end.q(kBeta), end.q(kGamma));
  return std::max((R_num - R_exact).cwiseAbs().maxCoeff(),
                  (end.q.head<3>() - p_exact).cwiseAbs().maxCoeff() / 0.1);  // m per 0.1 m
}

RunResult RunWith(const Scene& scene, const std::string& formulation, double step, double rtol,
              double atol) {
  RunSettings settings;
  settings.formulation = formulation;
  settings.options.step = step;
  settings.options.rtol = rtol;
  settings.options.atol = atol;
  return RunScene(scene, settings);
}

TEST(Newmark, SecondOrderOnTorqueFreePrecession) {
  const Scene scene = FreeTibiaScene();
  ASSERT_EQ(scene.model.inertia_T.x(), scene.model.inertia_T.y());  // the closed form needs it
  for (const char* name : {"newmark", "newmark-reduced"}) {
    std::vector<double> errors;
    for (double h : {4e-3, 2e-3, 1e-3, 5e-4}) {
      const RunResult r = RunWith(scene, name, h, 1e-13, 1e-15);
      ASSERT_TRUE(r.completed) << name << ": " << r.failure;
      ASSERT_NEAR(r.samples.back().t, 0.2, 1e-15);
      errors.push_back(FinalPoseError(scene, r.samples.back()));
    }
    for (size_t i = 0; i + 1 < errors.size(); ++i) {
      const double order = std::log2(errors[i] / errors[i + 1]);
      std::printf("%s h-ratio 2: error %.3e -> %.3e, order %.3f\n", name, errors[i], errors[i + 1], order);
      EXPECT_NEAR(order, 2.0, 0.2) << name << " errors " << errors[i] << " -> " << errors[i + 1];
    }
  }
}

// The lateral lift-off that ends contact for good (the last lift-off event) and the 90°
// time. Newmark's N carries an O(h) period-2 oscillation, so just before the true lift-off
// it can dip below zero once and re-contact (measured at h = 1e-4 s: liftoff 0.215590 s,
// re-contact 0.215637 s, then the final lift-off).
struct ChapterEvents {
  double liftoff_t = NAN, liftoff_deg = NAN, flexion90_t = NAN;
};
ChapterEvents Summarize(const RunResult& r) {
  ChapterEvents out;
  for (const EventRecord& e : r.events) {
    if (e.name == "liftoff_lateral") {
      out.liftoff_t = e.time;
      out.liftoff_deg = RadToDeg(e.flexion);
    }
    if (e.name == "flexion_90") out.flexion90_t = e.time;
  }
  return out;
}

TEST(Newmark, AgreesWithDaeOnChapterScene) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  const RunResult ref = RunWith(scene, "dae", 0.0, 1e-10, 1e-12);
  ASSERT_TRUE(ref.completed) << ref.failure;
  const ChapterEvents d = Summarize(ref);
  for (const char* name : {"newmark", "newmark-reduced"}) {
    const RunResult r = RunWith(scene, name, 1e-4, 1e-10, 1e-12);
    ASSERT_TRUE(r.completed) << name << ": " << r.failure;
    EXPECT_EQ(r.end_reason, "flexion_90");
    const ChapterEvents n = Summarize(r);
    // Measured (h = 1e-4 s, both forms): lift-off +25 µs / +0.010°, 90° +1 µs.
    EXPECT_NEAR(n.liftoff_t, d.liftoff_t, 1.0e-4) << name;
    EXPECT_NEAR(n.liftoff_deg, d.liftoff_deg, 0.05) << name;
    EXPECT_NEAR(n.flexion90_t, d.flexion90_t, 1.0e-5) << name;
    EXPECT_GT(r.stats.steps, 2900);  // ~0.3 s / 1e-4 s
    EXPECT_GT(r.stats.nonlinear_iterations, r.stats.steps);
  }
}

// newmark's own normal force oscillates from step to step (the trapezoidal rule does not damp
// the index-3 error modes), so its lift-off root can fire where the knee's force is not zero.
// On the chapter scene at the defaults (h = 1e-4 s, rtol 1e-6) it lifts off 0.7 ms before
// dae; the state there, solved with the contact kept (the hidden constraint: ede's physics, not
// newmark's multiplier), holds 4.3 N, 1.8 % of the contact's peak. The run warns of it
// (liftoff_force_not_zero); before, it said nothing. dae's lift-off holds < 1e-3 N and is not
// warned. (A smaller step makes it worse: at h = 2.5e-6 s the same scene gives nine lift-offs.)
TEST(Newmark, AnEarlyLiftoffOnItsOscillatingForceIsWarned) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  RunSettings dae_settings;
  dae_settings.formulation = "dae";
  RunSettings newmark_settings;
  newmark_settings.formulation = "newmark";
  const RunResult dae = RunScene(scene, dae_settings);
  const RunResult newmark = RunScene(scene, newmark_settings);
  ASSERT_TRUE(dae.completed) << dae.failure;
  ASSERT_TRUE(newmark.completed) << newmark.failure;
  ASSERT_FALSE(dae.events.empty());
  ASSERT_FALSE(newmark.events.empty());
  ASSERT_EQ(newmark.events[0].name, "liftoff_lateral");
  EXPECT_LT(newmark.events[0].time, dae.events[0].time - 5e-4) << "no early lift-off to warn of any more";
  EXPECT_LT(std::abs(dae.events[0].consistent_normal_force), 1e-3);
  EXPECT_GT(std::abs(newmark.events[0].consistent_normal_force), 1.0);
  const auto force_warnings = [&scene](const RunResult& r) {
    std::vector<OutputWarning> found;
    for (const OutputWarning& w : OutputWarnings(MakeTrajectoryTable(scene, r), r)) {
      if (w.kind == "liftoff_force_not_zero") found.push_back(w);
    }
    return found;
  };
  const std::vector<OutputWarning> warned = force_warnings(newmark);
  ASSERT_EQ(warned.size(), 1u);
  EXPECT_EQ(warned[0].time_s, newmark.events[0].time);
  EXPECT_EQ(warned[0].column, "N_lateral_N");
  EXPECT_EQ(warned[0].force_N, newmark.events[0].consistent_normal_force);
  EXPECT_TRUE(force_warnings(dae).empty());
}

// A scene that ends within one default step (1e-4 s) is run with its end time as the step
// (README, `--step`); a longer step given explicitly is refused.
TEST(Newmark, DefaultStepNeverExceedsTheEndTime) {
  Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  scene.end.time = 5.0e-5;
  for (const char* name : {"newmark", "generalized-alpha"}) {
    const RunResult r = RunWith(scene, name, 0.0, 1e-6, 1e-8);
    ASSERT_TRUE(r.completed) << name << ": " << r.failure;
    EXPECT_EQ(r.end_reason, "end_time") << name;
    EXPECT_EQ(r.fixed_step, 5.0e-5) << name;
    ASSERT_FALSE(r.samples.empty());
    EXPECT_EQ(r.samples.back().t, 5.0e-5) << name;
    EXPECT_THROW(RunWith(scene, name, 1.0e-4, 1e-6, 1e-8), InputError) << name;
  }
}

// The exact step tangent (blocks of solver/newton_euler_jacobian.hpp) against the Jet<24>
// tangent (--jacobian jet): both are the exact derivative, so Newton takes the same number
// of iterations (an error of 1e-3 in the tangent makes Newton linear with that rate and
// costs about one more iteration per step at these tolerances) and converges to the same
// states. Chapter and closed form, Newmark and generalized-α, h = 1e-3 s.
// The exact tangent (StepJacobian: the blocks of solver/newton_euler_jacobian.hpp) against
// the Jet<24> one (forward AD of the step residual, the reference), entry by entry, at
// states along the chapter run of each formulation (every output sample: impact, both
// contacts, the ligament kinks, lift-off), at the step's predictor and after one Newton
// step. Any wrong entry (a missing term, a wrong scheme slope γ/(βh), a sign) fails here;
// the observed difference is round-off (printed).
TEST(Newmark, ExactTangentEqualsTheJetTangent) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  const double h = 1e-3;
  for (const char* name : {"newmark", "newmark-reduced", "generalized-alpha", "generalized-alpha-reduced"}) {
    const std::string s = name;
    NewmarkOptions options;
    options.control.step = h;
    options.scheme = s.rfind("generalized-alpha", 0) == 0 ? ChungHulbertScheme(FormulationOptions().rho_inf)
                                                          : NewmarkScheme();
    const ContactForm form = s.find("reduced") != std::string::npos ? ContactForm::kClosedForm : ContactForm::kChapter;
    RunSettings settings;
    settings.formulation = name;
    settings.options.step = h;
    const RunResult run = RunScene(scene, settings);
    ASSERT_TRUE(run.completed) << name << ": " << run.failure;
    double worst = 0.0;
    int compared = 0;
    for (const MechanicalState& state : run.samples) {
      for (int newton_steps : {0, 1}) {
        MatrixXd exact, jet;
        ASSERT_TRUE(NewmarkTangentsForTesting(scene, options, form, state, h, newton_steps, &exact, &jet))
            << name << " t = " << state.t;
        ASSERT_EQ(exact.rows(), jet.rows());
        // Relative to each column's scale (the columns are m, rad and N unknowns).
        for (int c = 0; c < jet.cols(); ++c) {
          const double scale = std::max(jet.col(c).cwiseAbs().maxCoeff(), 1e-300);
          const double diff = (exact.col(c) - jet.col(c)).cwiseAbs().maxCoeff() / scale;
          worst = std::max(worst, diff);
          EXPECT_LE(diff, 1e-12) << name << " t = " << state.t << " s, column " << c << ", " << newton_steps
                                << " Newton steps";
        }
        ++compared;
      }
    }
    std::printf("%s: %d tangents, largest column-relative difference %.2e\n", name, compared, worst);
    EXPECT_GT(compared, 100) << name;
  }
}

// The same runs with either tangent: as many Newton iterations (a wrong or inaccurate
// tangent converges more slowly), and the same states up to the first ligament kink where
// the two runs can part by round-off. Why they part (generalized-alpha-reduced, h = 1e-3 s:
// 22 restarts with the Jet tangent, 21 with the exact one): the two tangents agree to
// ~1e-15 (test above), so the Newton iterates, hence the states, differ in the last bits;
// at t = 0.0312561 s the MCL's oblique bundle sits on its kink length, and the event is
// located to the locator's 1e-12 s bracket (formulations/internal/event_locator.hpp). With
// the Jet tangent the second location lands 5e-13 s before the length's own crossing, so the
// restarted phase sees it again 5e-13 s later: a third kink_MCL oblique restart that the
// exact run does not take. Each restart starts generalized-α afresh (PerturbedStart), so
// the runs then differ by the scheme's O(h²) error (2e-4 mm at 0.035 s), not by the tangent.
TEST(Newmark, ExactAndJetTangentRunsAgree) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  const double before_first_kink_tie = 0.031;  // s, see above
  for (const char* name : {"newmark", "newmark-reduced", "generalized-alpha", "generalized-alpha-reduced"}) {
    RunSettings settings;
    settings.formulation = name;
    settings.options.step = 1e-3;
    settings.options.rtol = 1e-10;
    settings.options.atol = 1e-12;
    settings.options.jacobian = JacobianKind::kJet;
    const RunResult jet = RunScene(scene, settings);
    settings.options.jacobian = JacobianKind::kExact;
    const RunResult exact = RunScene(scene, settings);
    ASSERT_TRUE(jet.completed && exact.completed) << name << ": " << jet.failure << exact.failure;
    EXPECT_NEAR(exact.stats.nonlinear_iterations, jet.stats.nonlinear_iterations,
                0.01 * jet.stats.nonlinear_iterations) << name;
    ASSERT_EQ(exact.samples.size(), jet.samples.size()) << name;
    const bool same_restarts = exact.stats.restarts == jet.stats.restarts;
    if (!same_restarts) {
      std::printf("%s: %ld and %ld restarts (exact, Jet): states compared before t = %g s\n", name,
                  static_cast<long>(exact.stats.restarts), static_cast<long>(jet.stats.restarts),
                  before_first_kink_tie);
      EXPECT_LE(std::abs(exact.stats.restarts - jet.stats.restarts), 1) << name;
      EXPECT_LE(std::abs(exact.stats.steps - jet.stats.steps), 1) << name;
    } else {
      EXPECT_EQ(exact.stats.steps, jet.stats.steps) << name;
    }
    int compared = 0;
    for (size_t k = 0; k < exact.samples.size(); ++k) {
      if (!same_restarts && exact.samples[k].t >= before_first_kink_tie) break;
      EXPECT_LE((exact.samples[k].q - jet.samples[k].q).cwiseAbs().maxCoeff(), 1e-9) << name << " sample " << k;
      ++compared;
    }
    EXPECT_GE(compared, 5) << name;
  }
}

// Newton cannot reach a tolerance below round-off: every step fails, is halved 20 times
// and the run ends with a SolverError that names t and h.
TEST(Newmark, NewtonFailureHalvesThenReportsTandH) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  const RunResult r = RunWith(scene, "newmark-reduced", 1e-4, 1e-19, 1e-22);
  EXPECT_FALSE(r.completed);
  EXPECT_EQ(r.stats.step_halvings, 20);
  EXPECT_NE(r.failure.find("t = "), std::string::npos) << r.failure;
  EXPECT_NE(r.failure.find("step h = "), std::string::npos) << r.failure;
  EXPECT_NE(r.failure.find("no convergence in 20 iterations"), std::string::npos) << r.failure;
}

// Near the JCS singularity every Newton solve throws the rotation map's SolverError; the
// final error must carry that reason, not only "did not converge after 20 halvings".
// jcs_crossing's exact motion is β(t) = 1° − 1 rad/s · t, so |sin β| < 1e-3 (the
// threshold of solver/rotation.hpp) from t* = (1° − asin 1e-3) / (1 rad/s) = 0.016453 s;
// jcs_near_pass adds α̇ = 0.2 rad/s and reaches it at about the same time.
TEST(Newmark, JcsSingularityFailureNamesTheReason) {
  const double t_star = (1.0 * M_PI / 180.0 - std::asin(1.0e-3)) / 1.0;
  for (const char* case_name : {"jcs_crossing", "jcs_near_pass"}) {
    const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/hard/" + case_name + ".yaml");
    for (const char* name : {"newmark", "newmark-reduced"}) {
      const RunResult r = RunWith(scene, name, 1e-4, 1e-6, 1e-8);
      EXPECT_FALSE(r.completed) << case_name << " " << name;
      EXPECT_NE(r.failure.find("halvings"), std::string::npos) << r.failure;
      EXPECT_NE(r.failure.find("JCS singularity"), std::string::npos) << case_name << " " << name << ": " << r.failure;
      ASSERT_FALSE(r.samples.empty());
      // It got as far as the last output before t*, and not past t*.
      EXPECT_GE(r.samples.back().t, t_star - scene.output_interval) << case_name << " " << name;
      EXPECT_LT(r.samples.back().t, t_star + 1e-4) << case_name << " " << name;
    }
  }
}

TEST(Newmark, RejectsOptionsItDoesNotUse) {
  const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  FormulationOptions options;
  options.stabilization = Stabilization::kBaumgarte;
  EXPECT_THROW(CreateFormulation("newmark", scene, options), InputError);
  options = FormulationOptions();
  options.max_step = 1e-3;
  EXPECT_THROW(CreateFormulation("newmark-reduced", scene, options), InputError);
}

}  // namespace
}  // namespace kneedyn
