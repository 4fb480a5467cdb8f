// Exact-solution verification of every registered formulation.
//
// Validates, for each formulation in RegisteredFormulations() (so new ones are picked up
// automatically), against closed-form solutions of the Newton–Euler equations (docs/model.md §8):
//   FreeFall     free tibia (no contact, no element) under gravity + a constant force:
//                R0(t) = R0 + v0 t + ½ (g + F/m) t², angles constant;
//   SpinningTop  torque-free symmetric top (Ixx′ = Iyy′ ≠ Izz′, chapter inertia): w_z′
//                constant, (w_x′, w_y′) turn at Ω = (Izz − Ixx)/Ixx · w_z′ in T, angular
//                momentum R_FT I w_T constant in F;
//   Hanging      tibia hanging by one element through its centre of mass along gravity,
//                linear region of the law (ε > 2ε1 checked at every sample): harmonic,
//                y0(t) = y_eq + (y0(0) − y_eq) cos(√(k_lin/m) t).
// Tolerances: adaptive methods run at rtol 1e-10, atol 1e-12; fixed-step methods
// (newmark*) at h = 1e-4 s, whose tolerance is ~20× the leading error term of the
// trapezoidal rule (phase error ω t (ω h)²/12) stated per test.
//   Manufactured the full knee (12 elements, C¹ law, both contacts, gravity) following
//                q*(t): α = 2 t², β = π/2 + 0.02 sin 5t, γ = 0.03 sin 4t, y0 = y0_ref +
//                1 mm · sin 6t, x0 and z0 from the two contact conditions (linear in R0,
//                docs/model.md §6). The extra load (model.hpp manufactured_load) is M (ν̇* − ν̇0),
//                ν̇0 the constrained acceleration without it at (q*, q̇*): it satisfies
//                G Δν̇ = 0, so q*(t) is the exact solution with the normal forces N0(t)
//                (checked > 0: both contacts stay closed). Checks the error against q* at
//                0.2 s and the convergence order: fixed-step methods ≈ 2 (newmark),
//                1 (euler), 4 (rk4) from step halving; adaptive ones: error falls with
//                the tolerance.
// Does not validate: contact switching (see the run conformance tests).
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <tuple>
#include <string>
#include <vector>

#include "formulations/run.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/error.hpp"
#include "solver/ligament.hpp"
#include "solver/units.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

bool IsFixedStep(const std::string& name) { return IsFixedStep(FindFormulation(name), ""); }

// Sensible options per formulation: fixed-step methods get h = 1e-4 s, adaptive ones
// (dae*, mde, ede with their default integrator) tight tolerances.
RunSettings SettingsFor(const std::string& name) {
  RunSettings s;
  s.formulation = name;
  s.options.rtol = 1.0e-10;
  s.options.atol = 1.0e-12;
  if (IsFixedStep(name)) s.options.step = kDefaultFixedStep;
  return s;
}


Scene Parse(const std::string& text, const std::string& label) {
  return ParseScene(text, label, ReferenceDataDir() + "/scenes");
}

std::string Num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Runs and checks the run completed at the end time.
RunResult RunToEnd(const Scene& scene, const std::string& name) {
  const RunResult r = RunScene(scene, SettingsFor(name));
  EXPECT_TRUE(r.completed) << name << ": " << r.failure;
  EXPECT_EQ(r.end_reason, "end_time");
  EXPECT_FALSE(r.samples.empty());
  if (!r.samples.empty()) {
    EXPECT_NEAR(r.samples.back().t, scene.end.time, 1e-12);
  }
  return r;
}

class ExactSolution : public ::testing::TestWithParam<std::string> {};

TEST_P(ExactSolution, FreeFallUnderGravityAndConstantForce) {
  const std::string name = GetParam();
  const Scene scene = Parse(R"(
name: exact_free_fall
parameter_set: ../chapter_knee.yaml
ligaments: none
contacts: []
gravity: {enabled: true}
pulse: {shape: none}
constant_load: {force_F_N: [3.0, 5.0, -2.0]}
initial_state:
  pose: reference
  velocities: {x0_mm_s: 10.0, y0_mm_s: -20.0, z0_mm_s: 30.0}
  hold: [x0, y0, z0, alpha, beta, gamma, velocities]
end: {time_s: 0.5}
output: {interval_s: 0.05}
)", "exact_free_fall.yaml");
  const RunResult r = RunToEnd(scene, name);
  const Model& m = scene.model;
  const Vector3d a = m.gravity_F + m.constant_load.force_F / m.mass;  // m/s²
  const Vector3d R0 = scene.initial.q.head<3>();
  const Vector3d v0 = scene.initial.qd.head<3>();
  ASSERT_NEAR(v0.z(), 0.030, 1e-15);  // mm/s converted to m/s
  // Both method classes integrate a quadratic exactly up to round-off and tolerance.
  const double tol = 1.0e-7;  // m, rad
  double max_err = 0.0;
  for (const MechanicalState& s : r.samples) {
    const Vector3d exact = R0 + v0 * s.t + 0.5 * a * s.t * s.t;
    max_err = std::max(max_err, (s.q.head<3>() - exact).cwiseAbs().maxCoeff());
    max_err = std::max(max_err, (s.q.tail<3>() - scene.initial.q.tail<3>()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(max_err, tol) << name;
  RecordProperty("max_error", Num(max_err));
  std::printf("[exact] %-16s free_fall    max |q - q_exact| = %.3e (m, rad)\n", name.c_str(), max_err);
}

TEST_P(ExactSolution, TorqueFreeSymmetricTop) {
  const std::string name = GetParam();
  // At the reference pose (α = 0, β = 90°, γ = 0) E = −I, so w_T = −(α̇, β̇, γ̇):
  // w_T(0) = (0.3, 0, 10) rad/s. Cone half-angle atan(Ixx w_x / (Izz w_z)) ≈ 21°, so β
  // stays within about 90° ± 42°, far from the JCS singularity.
  const double wx0 = 0.3, wz0 = 10.0;  // rad/s
  const Scene scene = Parse(StrCat(R"(
name: exact_spinning_top
parameter_set: ../chapter_knee.yaml
ligaments: none
contacts: []
gravity: {enabled: false}
pulse: {shape: none}
initial_state:
  pose: reference
  velocities: {alpha_deg_s: )", Num(-RadToDeg(wx0)), ", gamma_deg_s: ", Num(-RadToDeg(wz0)), R"(}
  hold: [x0, y0, z0, alpha, beta, gamma, velocities]
end: {time_s: 1.0}
output: {interval_s: 0.01}
)"), "exact_spinning_top.yaml");
  const Model& m = scene.model;
  const Vector3d I = m.inertia_T;
  ASSERT_DOUBLE_EQ(I.x(), I.y()) << "the symmetric-top solution needs Ixx' = Iyy'";
  const RunResult r = RunToEnd(scene, name);
  ASSERT_FALSE(r.samples.empty());
  const Vector3d w0 = AngularVelocityT(r.samples[0].q, r.samples[0].qd);
  ASSERT_NEAR((w0 - Vector3d(wx0, 0.0, wz0)).norm(), 0.0, 1e-12) << "initial w_T = " << w0.transpose();
  const double Omega = (I.z() - I.x()) / I.x() * wz0;  // rad/s, body-frame precession rate
  const Vector3d L0_F = PoseFromCoordinates(r.samples[0].q).R_FT * I.cwiseProduct(w0);
  // Fixed step: trapezoidal phase error ≈ ω t (ω h)²/12 with ω ≈ w_z = 10 rad/s, t = 1 s,
  // h = 1e-4 s: 8e-7; tolerance 2e-5 relative. Adaptive: 1e-6 relative.
  const double rel_tol = IsFixedStep(name) ? 2.0e-5 : 1.0e-6;
  double max_w_err = 0.0, max_L_err = 0.0, max_R0_err = 0.0;
  for (const MechanicalState& s : r.samples) {
    const Vector3d w = AngularVelocityT(s.q, s.qd);
    const Vector3d exact(wx0 * std::cos(Omega * s.t), wx0 * std::sin(Omega * s.t), wz0);
    max_w_err = std::max(max_w_err, (w - exact).norm() / w0.norm());
    const Vector3d L_F = PoseFromCoordinates(s.q).R_FT * I.cwiseProduct(w);
    max_L_err = std::max(max_L_err, (L_F - L0_F).norm() / L0_F.norm());
    max_R0_err = std::max(max_R0_err, (s.q.head<3>() - scene.initial.q.head<3>()).norm());
  }
  EXPECT_LT(max_w_err, rel_tol) << name;
  EXPECT_LT(max_L_err, rel_tol) << name;
  EXPECT_LT(max_R0_err, 1e-9) << name;
  std::printf("[exact] %-16s spinning_top max |w_T - exact|/|w| = %.3e, max |L_F - L_F(0)|/|L| = %.3e\n",
              name.c_str(), max_w_err, max_L_err);
}

TEST_P(ExactSolution, HangingByOneLinearElement) {
  const std::string name = GetParam();
  // Start 2 mm above the reference pose (element length 98 mm, linear region from
  // 96.364 mm); amplitude 1.64 mm about the equilibrium 99.636 mm.
  const double y0_ref_mm = -5.740280082863;
  const Scene scene = Parse(StrCat(R"(
name: exact_hanging
parameter_set: ../hanging_element_knee.yaml
ligaments: [hanger]
contacts: []
gravity: {enabled: true}
pulse: {shape: none}
initial_state:
  pose: reference
  coordinates: {y0_mm: )", Num(y0_ref_mm + 2.0), R"(}
  hold: [x0, y0, z0, alpha, beta, gamma, velocities]
end: {time_s: 0.5}
output: {interval_s: 0.005}
)"), "exact_hanging.yaml");
  const Model& m = scene.model;
  ASSERT_EQ(m.ligaments.size(), 1u);
  const Ligament& lig = m.ligaments[0];
  // The element must lie along −gravity through the centre of mass at the reference pose.
  const Vector3d up = -m.gravity_F.normalized();
  EXPECT_LT((lig.p_FoA_F - (scene.reference_q.head<3>() + 0.1 * up)).norm(), 1e-9);
  EXPECT_EQ(lig.p_ToB_T.norm(), 0.0);
  const double k = lig.k_linear, L0 = lig.slack_length, g = m.gravity_F.norm();
  const double omega = std::sqrt(k / m.mass);                            // rad/s
  const double y_att = lig.p_FoA_F.y();
  const double y_eq = y_att - (1.0 + kLigamentToeStrain) * L0 - m.mass * g / k;  // m
  const double y_start = scene.initial.q(kY0);
  const RunResult r = RunToEnd(scene, name);
  // Fixed step: phase error ω t (ω h)²/12 · amplitude = 40.4 · 0.5 · (4.04e-3)²/12 ·
  // 1.64 mm ≈ 4.5e-8 m; tolerance 1e-6 m. Adaptive: 1e-8 m (6e-6 of the amplitude).
  const double tol = IsFixedStep(name) ? 1.0e-6 : 1.0e-8;
  double max_err = 0.0, min_strain = 1e300;
  for (const MechanicalState& s : r.samples) {
    const double exact = y_eq + (y_start - y_eq) * std::cos(omega * s.t);
    max_err = std::max(max_err, std::abs(s.q(kY0) - exact));
    for (int i : {kX0, kZ0, kAlpha, kBeta, kGamma}) {
      max_err = std::max(max_err, std::abs(s.q(i) - scene.initial.q(i)));
    }
    const double length = LigamentSpan_F(lig, PoseFromCoordinates(s.q)).norm();
    min_strain = std::min(min_strain, LigamentStrain(lig, length));
  }
  EXPECT_GT(min_strain, 2.0 * kLigamentToeStrain) << "left the linear region: solution not exact";
  EXPECT_LT(max_err, tol) << name;
  std::printf("[exact] %-16s hanging      max |q - q_exact| = %.3e m (min strain %.4f)\n",
              name.c_str(), max_err, min_strain);
}

// ---- Manufactured solution for the full knee -------------------------------------------

constexpr double kManufacturedNormalForce = 200.0;  // N*, each contact
constexpr double kY0Ref = -5.740280082863e-3;  // m, chapter_knee.yaml reference_pose.y0_mm

// q*(t) with x0, z0 from the two closed-form contact conditions (as SolveReferencePose).
Vector6d ManufacturedQ(const Model& model, double t) {
  Vector6d q;
  q(kAlpha) = 2.0 * t * t;
  q(kBeta) = M_PI / 2.0 + 0.02 * std::sin(5.0 * t);
  q(kGamma) = 0.03 * std::sin(4.0 * t);
  q(kY0) = kY0Ref + 1.0e-3 * std::sin(6.0 * t);
  const Matrix3d R = RotationFT(q(kAlpha), q(kBeta), q(kGamma));
  Eigen::Matrix2d A;
  Eigen::Vector2d b;
  for (int row = 0; row < 2; ++row) {
    const SphereOnPlane& s = test_support::SopOf(model.contacts[row]);
    const Vector3d n = R * s.normal_T;
    A(row, 0) = n.x();
    A(row, 1) = n.z();
    b(row) = n.dot(s.centre_F) - s.offset - s.radius - n.y() * q(kY0);
  }
  const Eigen::Vector2d xz = A.fullPivLu().solve(b);
  q(kX0) = xz(0);
  q(kZ0) = xz(1);
  return q;
}

// q̇*, q̈* by fourth-order central differences (h = 1e-3 s: truncation ~1e-12, round-off
// ~1e-10 in q̈; both far below the errors measured).
void ManufacturedRates(const Model& model, double t, Vector6d* qd, Vector6d* qdd) {
  const double h = 1.0e-3;
  const Vector6d m2 = ManufacturedQ(model, t - 2 * h), m1 = ManufacturedQ(model, t - h);
  const Vector6d p1 = ManufacturedQ(model, t + h), p2 = ManufacturedQ(model, t + 2 * h);
  const Vector6d c = ManufacturedQ(model, t);
  *qd = (-p2 + 8.0 * p1 - 8.0 * m1 + m2) / (12.0 * h);
  *qdd = (-p2 + 16.0 * p1 - 30.0 * c + 16.0 * m1 - m2) / (12.0 * h * h);
}

// The manufactured-solution scenes' knee: all ligaments (C¹ law), both contacts, gravity, no
// pulse.
constexpr const char* kManufacturedKnee = R"(parameter_set: ../chapter_knee.yaml
ligaments: all
ligament_law: c1_continuous
contacts: [medial, lateral]
gravity: {enabled: true}
pulse: {shape: none}
)";

struct ManufacturedScene {
  Scene scene;
  double min_normal_force = 1e300;  // N, over a fine time grid
  double max_construction_error = 0.0;  // max |ν̇(q*, q̇*) − ν̇*|, SI
};

ManufacturedScene MakeManufacturedScene(double t_end) {
  // Velocities: the rates of the held quantities at t = 0; x0_dot, z0_dot follow from the
  // velocity level of the consistent initialization.
  Scene probe = Parse(StrCat("name: probe\n", kManufacturedKnee, "initial_state: {pose: reference}\nend: {time_s: 1.0}\n"),
                      "probe.yaml");
  Vector6d qd0, qdd0;
  ManufacturedRates(probe.model, 0.0, &qd0, &qdd0);
  ManufacturedScene ms;
  ms.scene = Parse(StrCat("name: manufactured_knee\n", kManufacturedKnee, R"(
initial_state:
  pose: reference
  velocities: {x0_mm_s: )", Num(MToMm(qd0(kX0))), ", y0_mm_s: ", Num(MToMm(qd0(kY0))),
      ", z0_mm_s: ", Num(MToMm(qd0(kZ0))), ", alpha_deg_s: ", Num(RadToDeg(qd0(kAlpha))),
      ", beta_deg_s: ", Num(RadToDeg(qd0(kBeta))), ", gamma_deg_s: ", Num(RadToDeg(qd0(kGamma))), R"(}
  hold: [alpha, beta, gamma, y0, alpha_dot, beta_dot, gamma_dot, y0_dot]
end: {time_s: )", Num(t_end), R"(}
output: {interval_s: 0.01}
)"), "manufactured_knee.yaml");
  const Model base = ms.scene.model;  // without the extra load
  const std::vector<int> both = {0, 1};
  ms.scene.model.manufactured_load = [base, both](double t, Vector3d* f_F, Vector3d* tau_T) {
    Vector6d q = ManufacturedQ(base, t), qd, qdd;
    ManufacturedRates(base, t, &qd, &qdd);
    const ConstrainedAcceleration ca = SolveConstrainedAcceleration(base, t, q, qd, both);
    const Vector6d nu_dot = GeneralizedAcceleration(q, qd, qdd);
    // M Δν̇ moves the motion onto q*; Gᵀ (N0 − N*) (range of Gᵀ: no motion) sets the
    // normal forces to N* = 200 N each, so both contacts stay closed.
    Vector6d extra = MassTimes(base, Vector6d(nu_dot - ca.nu_dot));
    const Pose pose = PoseFromCoordinates(q);
    const std::vector<ContactGeometry> geo = ClosedFormContacts(base, pose, both);
    for (size_t i = 0; i < both.size(); ++i) {
      extra += ContactConstraintRow(pose, geo[i]).transpose() * (ca.normal_force[i] - kManufacturedNormalForce);
    }
    *f_F = extra.head<3>();
    *tau_T = extra.tail<3>();
  };
  // Check of the construction with the loaded model: along q*, the constrained
  // acceleration is ν̇* and the normal forces are N*.
  for (double t = 0.0; t <= t_end + 1e-12; t += 1e-3) {
    Vector6d q = ManufacturedQ(base, t), qd, qdd;
    ManufacturedRates(base, t, &qd, &qdd);
    const ConstrainedAcceleration ca = SolveConstrainedAcceleration(ms.scene.model, t, q, qd, both);
    for (double n : ca.normal_force) ms.min_normal_force = std::min(ms.min_normal_force, n);
    ms.max_construction_error = std::max(
        ms.max_construction_error, (ca.nu_dot - GeneralizedAcceleration(q, qd, qdd)).cwiseAbs().maxCoeff());
  }
  return ms;
}

// Max |q − q*| over the output samples (m and rad mixed: both ~1e-1 in size here).
double ManufacturedError(const Scene& scene, const RunResult& r) {
  double e = 0.0;
  for (const MechanicalState& s : r.samples) {
    e = std::max(e, (s.q - ManufacturedQ(scene.model, s.t)).cwiseAbs().maxCoeff());
  }
  return e;
}

// Max |N − N*| over the output samples from t_from on, both contacts (N* = 200 N, exact).
double ManufacturedForceError(const RunResult& r, double t_from) {
  double e = 0.0;
  for (const MechanicalState& s : r.samples) {
    if (s.t < t_from - 1e-12) continue;
    for (int c : s.active) e = std::max(e, std::abs(s.contact[c].normal_force - kManufacturedNormalForce));
  }
  return e;
}

RunResult RunManufactured(const Scene& scene, const RunSettings& settings) {
  const RunResult r = RunScene(scene, settings);
  EXPECT_TRUE(r.completed) << settings.formulation << " " << IntegratorOptionName(settings.options.integrator) << ": " << r.failure;
  EXPECT_EQ(r.end_reason, "end_time") << settings.formulation;
  for (const EventRecord& e : r.events) ADD_FAILURE() << "unexpected event " << e.name << " at " << e.time;
  return r;
}

TEST_P(ExactSolution, ManufacturedKneeConvergesAtTheoreticalOrder) {
  const std::string name = GetParam();
  const double t_end = 0.2;  // s
  const ManufacturedScene ms = MakeManufacturedScene(t_end);
  ASSERT_NEAR(ms.min_normal_force, kManufacturedNormalForce, 1e-6) << "q* must keep both contacts closed";
  ASSERT_LT(ms.max_construction_error, 1e-6);
  const Scene& scene = ms.scene;
  // The extra load is a correction, not the whole motion: check it is not zero.
  Vector3d f, tau;
  scene.model.manufactured_load(0.1, &f, &tau);
  EXPECT_GT(f.norm() + tau.norm(), 1e-3);

  auto error_at = [&](RunSettings s) { return ManufacturedError(scene, RunManufactured(scene, s)); };
  if (IsFixedStep(name)) {
    RunSettings s = SettingsFor(name);
    s.options.step = 2.0e-3;
    const double e1 = error_at(s);
    s.options.step = 1.0e-3;
    const double e2 = error_at(s);
    const double order = std::log2(e1 / e2);
    std::printf("[exact] %-16s manufactured h = 2e-3: %.3e, h = 1e-3: %.3e, order %.2f\n",
                name.c_str(), e1, e2, order);
    EXPECT_NEAR(order, 2.0, 0.3) << name;
    EXPECT_LT(e2, 1e-4) << name;
    if (name.rfind("generalized-alpha", 0) == 0) {
      // Arnold & Brüls (2007): second order in positions and multipliers. With the
      // exact start (q̇_0, a_0 = q̈(t_0 + Δα h)) the multipliers had an initial layer of O(h)
      // errors damped like ρ∞ⁿ (max |N − N*| over the run 4.7e-3/2.3e-3/1.1e-3 N, first
      // order); the perturbed start (newmark.cpp, PerturbedStart: q̇_0 + h²(1/6 − Δα/2 − β) q⃛_0)
      // removes it. Checked over the whole run, a band of ±0.2: positions from
      // h = 1e-3 to 5e-4, forces from 2e-3 to 1e-3 (at 5e-4 the chapter form gives 2.0e-6 N
      // against the closed form's 1.6e-6 N, order 1.8; attributed, not verified, to the Newton
      // acceptance for N: q updates accepted below 1e-3 of their tolerance, ~1e-13 m, leave N
      // unresolved by ~M · 1e-13 m / h² ≈ 1e-6 N; bounded instead).
      std::vector<double> ep, en;
      for (double h : {2.0e-3, 1.0e-3, 5.0e-4}) {
        s.options.step = h;
        const RunResult r = RunManufactured(scene, s);
        ep.push_back(ManufacturedError(scene, r));
        en.push_back(ManufacturedForceError(r, 0.0));
      }
      const double order_q = std::log2(ep[1] / ep[2]), order_n = std::log2(en[0] / en[1]);
      std::printf("[exact] %-16s manufactured h = 2e-3/1e-3/5e-4: q %.3e %.3e %.3e (order %.2f), "
                  "N (whole run) %.3e %.3e %.3e N (order %.2f)\n", name.c_str(), ep[0], ep[1], ep[2], order_q,
                  en[0], en[1], en[2], order_n);
      EXPECT_NEAR(order_q, 2.0, 0.2) << name;
      EXPECT_NEAR(order_n, 2.0, 0.2) << name;
      EXPECT_LT(en[2], 2.5e-6) << name;  // N: ≤ second-order extrapolation 1.75e-6 + Newton floor
    }
    return;
  }
  // Adaptive (default integrator): error decreases with the tolerance.
  std::vector<double> errs;
  for (double rtol : {1e-6, 1e-8, 1e-10}) {
    RunSettings s = SettingsFor(name);
    s.options.rtol = rtol;
    s.options.atol = rtol * 1e-2;
    errs.push_back(error_at(s));
  }
  std::printf("[exact] %-16s manufactured rtol 1e-6/1e-8/1e-10: %.3e %.3e %.3e\n", name.c_str(),
              errs[0], errs[1], errs[2]);
  EXPECT_LT(errs[1], errs[0]) << name;
  EXPECT_LT(errs[2], errs[1]) << name;
  EXPECT_LT(errs[2], 1e-7) << name;
  // Fixed-step integrators the formulation offers: euler order 1, rk4 order 4.
  const FormulationInfo& info = FindFormulation(name);
  for (const auto& [integrator, order, h] :
       std::vector<std::tuple<std::string, double, double>>{{"euler", 1.0, 2e-4}, {"rk4", 4.0, 4e-3}}) {
    const IntegratorKind kind = ParsedOptionValue<IntegratorKind>(integrator);
    if (std::find(info.integrators.begin(), info.integrators.end(), kind) == info.integrators.end()) continue;
    RunSettings s = SettingsFor(name);
    s.options.integrator = kind;
    s.options.step = h;
    const double e1 = error_at(s);
    s.options.step = h / 2.0;
    const double e2 = error_at(s);
    const double observed = std::log2(e1 / e2);
    std::printf("[exact] %-16s manufactured %s h = %.0e: %.3e, h/2: %.3e, order %.2f\n", name.c_str(),
                integrator.c_str(), h, e1, e2, observed);
    EXPECT_NEAR(observed, order, 0.3 * order) << name << " " << integrator;
  }
}

INSTANTIATE_TEST_SUITE_P(AllFormulations, ExactSolution, ::testing::ValuesIn(test_support::RegisteredFormulationNames()),
                         test_support::FormulationParamName());

}  // namespace
}  // namespace kneedyn
