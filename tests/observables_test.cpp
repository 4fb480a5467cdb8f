// Tests of the observables of a state (solver/observables.hpp) and of the trajectory
// table built from them (formulations/run_output.cpp).
//
// Validates:
//  - energies against a hand computation: kinetic from w_T obtained by differencing the
//    rotation matrix (w_T× = Rᵀ Ṙ, not the angular-velocity map), load potential −(m g + F)·R0
//    with a constant load added, ligament strain energy from the integral of Eq. 1.14
//    written here; the total equals MechanicalEnergy (dynamics.hpp) bit for bit;
//  - ligament length, strain and tension from the law written here at lengths measured from
//    the attachments, on a model with one ligament fewer and one contact fewer;
//  - contact points: at a consistent pose the femoral point is C − r n_F (sphere on plane,
//    from the surface data), from both sources, and the normal force passes through;
//  - the trajectory table's columns follow the model's counts (19 + 9 per contact + 3 per
//    ligament; the chapter's 73), names of removed elements are absent, every row has one
//    value per column, and its values equal the observables;
//  - a real run (dae and mde) of the chapter scene without its lateral compartment and one
//    ligament: 61 columns, forces on the law at the reported lengths, the two formulations
//    agree on the time of 90° flexion.
// Does not validate: the file formatting (output_publish_test, cli_test).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "formulations/run_output.hpp"
#include "solver/consistent_init.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/dynamics.hpp"
#include "solver/observables.hpp"
#include "solver/rotation.hpp"
#include "solver/units.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;
using test_support::SopOf;

double HandTension(const Ligament& lig, double L) {
  const double L0 = lig.slack_length, e1 = 0.03;
  if (L <= L0) return 0.0;
  if (L - L0 <= 2 * e1 * L0) return lig.k_parabolic * (L - L0) * (L - L0);
  return lig.k_linear * (L - (1 + e1) * L0);
}

double HandPotential(const Ligament& lig, double L) {
  const double L0 = lig.slack_length, e1 = 0.03;
  if (L <= L0) return 0.0;
  const double x = L - L0, xk = 2 * e1 * L0;
  if (x <= xk) return lig.k_parabolic * x * x * x / 3.0;
  return lig.k_parabolic * xk * xk * xk / 3.0 +
         0.5 * lig.k_linear * ((x - e1 * L0) * (x - e1 * L0) - (xk - e1 * L0) * (xk - e1 * L0));
}

double HandLength(const Ligament& lig, const Vector6d& q) {
  const Matrix3d R = RotationFT(q(kAlpha), q(kBeta), q(kGamma));
  return (lig.p_FoA_F - (q.head<3>() + R * lig.p_ToB_T)).norm();
}

TEST(Observables, EnergiesMatchHandComputation) {
  Model model = ChapterScene().model;
  model.constant_load.force_F = Vector3d(3.0, -2.0, 5.0);
  Vector6d q = ChapterScene().initial.q, qd;
  q(kAlpha) += 0.4;
  q(kZ0) += 2e-3;  // stretch the ligaments into both regions of the law
  qd << 0.03, -0.02, 0.05, 2.0, 0.4, -0.7;
  const EnergyObservables e = ComputeEnergies(model, q, qd);

  // w_T× = Rᵀ Ṙ by a central difference of R along q + t q̇.
  const double h = 1e-6;
  auto R = [&](const Vector6d& x) { return RotationFT(x(kAlpha), x(kBeta), x(kGamma)); };
  const Matrix3d W = R(q).transpose() * (R(q + h * qd) - R(q - h * qd)) / (2 * h);
  const Vector3d w(W(2, 1), W(0, 2), W(1, 0));
  const double kinetic = 0.5 * model.mass * qd.head<3>().squaredNorm() +
                         0.5 * (model.inertia_T(0) * w(0) * w(0) + model.inertia_T(1) * w(1) * w(1) +
                                model.inertia_T(2) * w(2) * w(2));
  EXPECT_NEAR(e.kinetic, kinetic, 1e-8 * kinetic);
  EXPECT_DOUBLE_EQ(e.load_potential,
                   -(model.mass * model.gravity_F + model.constant_load.force_F).dot(q.head<3>()));
  double lig = 0.0;
  int stretched = 0;
  for (const Ligament& l : model.ligaments) {
    lig += HandPotential(l, HandLength(l, q));
    stretched += HandLength(l, q) > (1 + 0.06) * l.slack_length;
  }
  ASSERT_GT(stretched, 0) << "some element must be in the linear region";
  ASSERT_GT(lig, 0.0);
  EXPECT_NEAR(e.ligament_potential, lig, 1e-12 * lig);
  EXPECT_NEAR(e.mechanical, e.kinetic + e.load_potential + e.ligament_potential, 1e-12 * std::abs(e.mechanical));
  EXPECT_EQ(e.mechanical, MechanicalEnergy(model, q, qd));  // same sum, same order
}

// The chapter model with its first ligament and its lateral contact removed.
Model SmallerModel() {
  Model model = ChapterScene().model;
  model.ligaments.erase(model.ligaments.begin());
  const int lateral = model.ContactIndex(Compartment::kLateral);
  model.contacts.erase(model.contacts.begin() + lateral);
  return model;
}

TEST(Observables, LigamentsFollowTheLawOnAModelWithFewerElements) {
  const Model model = SmallerModel();
  ASSERT_EQ(model.ligaments.size(), ChapterScene().model.ligaments.size() - 1);
  MechanicalState s;
  s.q = ChapterScene().initial.q;
  s.q(kZ0) += 1.5e-3;
  s.q(kAlpha) += 0.2;
  s.contact.resize(model.contacts.size());
  Observables obs;
  ComputeObservables(model, s, ContactPointSource::kPose, &obs);
  ASSERT_EQ(obs.ligaments.size(), model.ligaments.size());
  ASSERT_EQ(obs.contacts.size(), 1u);
  for (size_t k = 0; k < model.ligaments.size(); ++k) {
    const Ligament& l = model.ligaments[k];
    const double L = HandLength(l, s.q);
    EXPECT_NEAR(obs.ligaments[k].length, L, 1e-15) << l.name;
    EXPECT_NEAR(obs.ligaments[k].strain, (L - l.slack_length) / l.slack_length, 1e-12) << l.name;
    EXPECT_NEAR(obs.ligaments[k].tension, HandTension(l, L), 1e-9 * (1 + HandTension(l, L))) << l.name;
  }
  EXPECT_FALSE(obs.contacts[0].active);
  EXPECT_TRUE(std::isnan(obs.contacts[0].point_F.x()));
  EXPECT_EQ(obs.contacts[0].normal_force, 0.0);
  EXPECT_TRUE(std::isfinite(obs.contacts[0].gap)) << "residuals exist for every pair";
}

TEST(Observables, ContactPointsAtConsistentPoseFromBothSources) {
  const Scene& scene = ChapterScene();
  ConsistentInitOptions o;
  InitReport report;
  const MechanicalState s = ConsistentInitialize(scene.model, scene.initial, {0, 1}, o, &report);
  const Pose pose = PoseFromCoordinates(s.q);
  for (ContactPointSource source : {ContactPointSource::kStateCoordinates, ContactPointSource::kPose}) {
    Observables obs;
    ComputeObservables(scene.model, s, source, &obs);
    ASSERT_EQ(obs.contacts_active, 2);
    for (int c : {0, 1}) {
      const SphereOnPlane sop = SopOf(scene.model.contacts[c]);
      const Vector3d expected_F = sop.centre_F - sop.radius * (pose.R_FT * sop.normal_T);
      const ContactObservables& co = obs.contacts[c];
      ASSERT_TRUE(co.point_found);
      EXPECT_LT((co.point_F - expected_F).norm(), 1e-9) << c;
      EXPECT_LT((pose.PointInF(co.point_T) - expected_F).norm(), 1e-9) << c;  // same point
      EXPECT_EQ(co.normal_force, s.contact[c].normal_force);
      EXPECT_GT(co.normal_force, 0.0);
      EXPECT_NEAR(co.gap, 0.0, 1e-10);
      EXPECT_LT(co.femoral_slope, 10.0);  // chapter start: low on the condyle
    }
  }
}

// The output columns omega_*_T_deg_s are the angular velocity in the tibial frame T
// (docs/outputs.md): w_T× = Rᵀ Ṙ, by a central difference of R_FT along q + t q̇, at a pose
// turned about all three JCS axes (in F the vector differs: R_FT w_T).
TEST(Observables, AngularVelocityIsInTheTibialFrame) {
  const Scene& scene = ChapterScene();
  ConsistentInitOptions options;
  InitReport report;
  MechanicalState s = ConsistentInitialize(scene.model, scene.initial, {0, 1}, options, &report);
  s.q(kAlpha) += 0.8;
  s.q(kBeta) += 0.2;
  s.q(kGamma) += -0.3;
  s.qd << 0.01, -0.02, 0.005, 2.0, 0.4, 0.5;
  Observables o;
  ComputeObservables(scene.model, s, ContactPointSource::kStateCoordinates, &o, kObserveNothingMore);
  const double h = 1e-6;
  auto R = [](const Vector6d& x) { return RotationFT(x(kAlpha), x(kBeta), x(kGamma)); };
  const Matrix3d W = R(s.q).transpose() * (R(s.q + h * s.qd) - R(s.q - h * s.qd)) / (2 * h);
  const Vector3d w_T(W(2, 1), W(0, 2), W(1, 0));
  EXPECT_LT((o.joint.omega_T - w_T).norm(), 1e-8 * w_T.norm()) << o.joint.omega_T.transpose() << " vs " << w_T.transpose();
  EXPECT_GT((R(s.q) * w_T - w_T).norm(), 0.1 * w_T.norm()) << "the pose must tell T from F";
}

// Without the extras (what the trajectory table asks for) every other field is the same
// bits as with them, the energies stay 0 and the slopes NaN; with each extra alone, that
// extra is the full call's.
TEST(Observables, ExtrasLeaveTheOtherFieldsAlone) {
  const Scene& scene = ChapterScene();
  ConsistentInitOptions o;
  InitReport report;
  MechanicalState s = ConsistentInitialize(scene.model, scene.initial, {0, 1}, o, &report);
  s.qd << 0.01, -0.02, 0.005, 1.5, 0.1, -0.2;
  s.t = 0.03;
  for (ContactPointSource source : {ContactPointSource::kStateCoordinates, ContactPointSource::kPose}) {
    Observables all, none, energies, slope;
    ComputeObservables(scene.model, s, source, &all);
    ComputeObservables(scene.model, s, source, &none, kObserveNothingMore);
    ComputeObservables(scene.model, s, source, &energies, kObserveEnergies);
    ComputeObservables(scene.model, s, source, &slope, kObserveFemoralSlope);
    EXPECT_NE(all.energy.kinetic, 0.0);
    EXPECT_NE(all.energy.mechanical, 0.0);
    EXPECT_EQ(none.energy.kinetic, 0.0);
    EXPECT_EQ(none.energy.mechanical, 0.0);
    EXPECT_EQ(energies.energy.mechanical, all.energy.mechanical);
    EXPECT_EQ(energies.energy.ligament_potential, all.energy.ligament_potential);
    EXPECT_EQ(slope.energy.mechanical, 0.0);
    EXPECT_EQ(none.t, all.t);
    EXPECT_EQ(none.pulse, all.pulse);
    EXPECT_EQ(none.joint.omega_T, all.joint.omega_T);
    ASSERT_EQ(none.contacts.size(), all.contacts.size());
    for (size_t c = 0; c < all.contacts.size(); ++c) {
      EXPECT_TRUE(std::isfinite(all.contacts[c].femoral_slope)) << c;
      EXPECT_EQ(slope.contacts[c].femoral_slope, all.contacts[c].femoral_slope) << c;
      EXPECT_TRUE(std::isnan(none.contacts[c].femoral_slope)) << c;
      EXPECT_TRUE(std::isnan(energies.contacts[c].femoral_slope)) << c;
      EXPECT_EQ(none.contacts[c].point_F, all.contacts[c].point_F) << c;
      EXPECT_EQ(none.contacts[c].point_T, all.contacts[c].point_T) << c;
      EXPECT_EQ(none.contacts[c].normal_force, all.contacts[c].normal_force) << c;
      EXPECT_EQ(none.contacts[c].gap, all.contacts[c].gap) << c;
      EXPECT_EQ(none.contacts[c].gap_rate, all.contacts[c].gap_rate) << c;
    }
    ASSERT_EQ(none.ligaments.size(), all.ligaments.size());
    for (size_t k = 0; k < all.ligaments.size(); ++k) {
      EXPECT_EQ(none.ligaments[k].length, all.ligaments[k].length) << k;
      EXPECT_EQ(none.ligaments[k].tension, all.ligaments[k].tension) << k;
    }
  }
}

TEST(TrajectoryTable, ColumnsFollowTheModelsCounts) {
  const Scene& chapter = ChapterScene();
  Scene scene = chapter;
  scene.model = SmallerModel();
  // Two samples of the smaller model: one in contact (medial), one separated.
  RunResult result;
  MechanicalState s;
  s.q = chapter.initial.q;
  s.q(kZ0) += 1e-3;
  s.contact.resize(1);
  result.samples.push_back(s);
  result.sample_is_event.push_back(false);
  s.t = 0.01;
  s.active = {0};
  s.contact[0].normal_force = 123.0;
  result.samples.push_back(s);
  result.sample_is_event.push_back(true);

  const size_t nl = scene.model.ligaments.size(), nc = scene.model.contacts.size();
  const TrajectoryTable t = MakeTrajectoryTable(scene, result);
  EXPECT_EQ(t.columns.size(), 19 + 9 * nc + 3 * nl);
  auto has = [&](const std::string& c) { return std::find(t.columns.begin(), t.columns.end(), c) != t.columns.end(); };
  EXPECT_TRUE(has("N_medial_N"));
  EXPECT_TRUE(has("gap_rate_medial_mm_s"));
  EXPECT_FALSE(has("N_lateral_N"));
  EXPECT_FALSE(has("femoral_lateral_x_mm"));
  EXPECT_FALSE(has("F_" + ColumnSafeName(chapter.model.ligaments[0].name) + "_N"));
  EXPECT_TRUE(has("L_" + ColumnSafeName(chapter.model.ligaments[1].name) + "_mm"));
  ASSERT_EQ(t.rows.size(), 2u);
  auto col = [&](const std::string& c) {
    return static_cast<size_t>(std::find(t.columns.begin(), t.columns.end(), c) - t.columns.begin());
  };
  for (const auto& row : t.rows) EXPECT_EQ(row.size(), t.columns.size());
  EXPECT_EQ(t.rows[0][col("N_medial_N")], 0.0);
  EXPECT_TRUE(std::isnan(t.rows[0][col("femoral_medial_x_mm")]));
  EXPECT_EQ(t.rows[1][col("N_medial_N")], 123.0);
  EXPECT_EQ(t.rows[1][col("contacts_active")], 1.0);
  for (size_t k = 0; k < nl; ++k) {
    const Ligament& l = scene.model.ligaments[k];
    const double L = HandLength(l, s.q);
    EXPECT_NEAR(t.rows[1][col("L_" + ColumnSafeName(l.name) + "_mm")], MToMm(L), 1e-12);
    EXPECT_NEAR(t.rows[1][col("F_" + ColumnSafeName(l.name) + "_N")], HandTension(l, L), 1e-9 * (1 + HandTension(l, L)));
  }

  // The chapter scene: both compartments, twelve elements, 73 columns (docs/outputs.md).
  RunResult one;
  MechanicalState c0;
  c0.q = chapter.initial.q;
  c0.contact.resize(2);
  one.samples.push_back(c0);
  one.sample_is_event.push_back(false);
  const TrajectoryTable full = MakeTrajectoryTable(chapter, one);
  EXPECT_EQ(full.columns.size(), 73u);
  EXPECT_EQ(full.rows[0].size(), 73u);
}

// A run of the chapter scene with its lateral compartment and one ligament removed, in
// two formulations: 19 + 9 + 3·11 = 61 columns; in every row the ligament forces follow the
// law at the reported lengths, the medial gap stays closed and its force compressive; both
// formulations reach 90° of flexion at the same time.
TEST(TrajectoryTable, RunOfASceneWithOneContactAndElevenLigaments) {
  Scene scene = ChapterScene();
  const int lateral = scene.model.ContactIndex(Compartment::kLateral);
  scene.model.contacts.erase(scene.model.contacts.begin() + lateral);
  scene.initial.contact_guesses.erase(scene.initial.contact_guesses.begin() + lateral);
  scene.model.ligaments.erase(scene.model.ligaments.begin() + 3);
  double t90[2] = {0.0, 0.0};
  int n = 0;
  for (const char* formulation : {"dae", "mde"}) {
    RunSettings settings;
    settings.formulation = formulation;
    settings.options.rtol = 1e-8;
    settings.options.atol = 1e-10;
    const RunResult r = RunScene(scene, settings);
    ASSERT_TRUE(r.completed) << formulation << ": " << r.failure;
    ASSERT_FALSE(r.events.empty());
    EXPECT_EQ(r.events.back().name, "flexion_90");
    t90[n++] = r.events.back().time;
    const TrajectoryTable t = MakeTrajectoryTable(scene, r);
    ASSERT_EQ(t.columns.size(), 61u) << formulation;
    auto col = [&](const std::string& c) {
      const auto it = std::find(t.columns.begin(), t.columns.end(), c);
      EXPECT_NE(it, t.columns.end()) << c;
      return static_cast<size_t>(it - t.columns.begin());
    };
    for (const auto& row : t.rows) {
      ASSERT_EQ(row.size(), t.columns.size());
      EXPECT_GT(row[col("N_medial_N")], 0.0);
      EXPECT_LT(std::abs(row[col("gap_medial_mm")]), 1e-4);
      for (const Ligament& l : scene.model.ligaments) {
        const double L = MmToM(row[col("L_" + ColumnSafeName(l.name) + "_mm")]);
        const double F = HandTension(l, L);
        EXPECT_NEAR(row[col("F_" + ColumnSafeName(l.name) + "_N")], F, 1e-9 * (1.0 + F)) << l.name;
      }
    }
  }
  EXPECT_NEAR(t90[0], t90[1], 1e-5) << "dae and mde disagree on the time of 90 deg";
}

}  // namespace
}  // namespace kneedyn
