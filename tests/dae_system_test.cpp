// Tests of the exact structured Jacobian of the chapter DAE (formulations/internal/dae_system.hpp,
// solver/newton_euler_jacobian.hpp).
//
// Validates: DaeSystem::Jacobian (blocks differentiated at their own size: applied loads
// analytically, kinematic part with Jet<5>, contacts in closed form in the regular chart or
// with Jet<10>) equals the Jet<24>
// derivative of the whole residual (JacobianByJets, itself checked against central
// differences in dae_test.cpp) to round-off, for every system the IDA formulations build:
// chapter and closed form, velocity and position level, plain and GGL (with μ ≠ 0, so the
// stabilization's own derivative counts), on sphere-on-plane surfaces (closed-form
// kinematics) and on the anatomical surfaces (the general local contact solve), with the
// ligaments on their natural branches and with every branch flipped (the locked-branch
// law of a phase). The free Newton–Euler partials are also checked against central
// differences of the double residual, independently of the Jets.
// Does not validate: IDA's use of the matrix (dae_test.cpp, conformance_test.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "formulations/internal/dae_system.hpp"
#include "scene/scene.hpp"
#include "solver/consistent_init.hpp"
#include "solver/newton_euler_jacobian.hpp"
#include "solver/units.hpp"
#include "tests/off_rest_state.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;
using test_support::MoveOffRest;
using test_support::ScenesDir;

const Scene& AnatomicalScene() {
  static const Scene scene = LoadScene(ScenesDir() + "/anatomical_surfaces.yaml");
  return scene;
}

struct Case {
  const char* scene;  // "chapter" | "anatomical"
  ContactForm form;
  ConstraintLevel level;
  bool ggl;
  bool flip_branches;
};

std::string CaseName(const Case& c) {
  return std::string(c.scene) + (c.form == ContactForm::kChapter ? "_chapter" : "_closed") +
         (c.ggl ? "_ggl" : c.level == ConstraintLevel::kPosition ? "_position" : "_velocity") +
         (c.flip_branches ? "_flipped" : "");
}
void PrintTo(const Case& c, std::ostream* os) { *os << CaseName(c); }

class DaeSystemJacobian : public ::testing::TestWithParam<Case> {};

// A consistent start moved away from rest (random rates, accelerations, contact
// coordinates, forces and multipliers: the residual need not vanish for a derivative check).
TEST_P(DaeSystemJacobian, ExactBlocksEqualTheJetDerivative) {
  const Case& c = GetParam();
  const Scene& scene = std::string(c.scene) == "chapter" ? ChapterScene() : AnatomicalScene();
  ConsistentInitOptions init;
  init.form = c.form;
  MechanicalState s = ConsistentInitialize(scene.model, scene.initial, {0, 1}, init, nullptr);
  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  MoveOffRest(scene.model, &rng, &s);
  if (c.flip_branches) {
    for (signed char& b : s.ligament_branch) b = b == kBranchToe ? kBranchLinear : kBranchToe;
  }
  DaeSystem system(scene.model, c.form, c.level, c.ggl);
  system.SetPhase(s.active, s.contact, s.ligament_branch);
  const int n = system.size();
  std::vector<double> y(n), yp(n);
  system.InitialValues(s, y.data(), yp.data());
  for (int i = 12; i < system.NormalIndex(0); ++i) {
    y[i] += MmToM(0.2) * u(rng);  // contact coordinates (m or rad of the regular chart)
    yp[i] += 1e-3 * u(rng);
  }
  for (int k = 0; k < 2; ++k) y[system.NormalIndex(k)] += 10.0 * u(rng);
  if (c.ggl) {
    for (int k = 0; k < 2; ++k) y[system.MuIndex(k)] = 0.3 * u(rng);  // m/s, rad/s scale
  }
  const double cj = 850.0;  // a typical α/h (1/s)
  std::vector<double> exact(n * n), jet(n * n);
  ASSERT_TRUE(system.Jacobian(s.t, cj, y.data(), yp.data(), exact.data()));
  ASSERT_TRUE(system.JacobianByJets(s.t, cj, y.data(), yp.data(), jet.data()));
  double largest = 0.0;
  for (double v : jet) largest = std::max(largest, std::abs(v));
  for (int col = 0; col < n; ++col) {
    for (int row = 0; row < n; ++row) {
      const double a = exact[row + n * col], b = jet[row + n * col];
      // Both are exact derivatives: they differ by the round-off of different operation
      // orders, relative to the entry and to the matrix's scale.
      EXPECT_NEAR(a, b, 1e-12 * largest + 1e-10 * std::abs(b))
          << "dF[" << row << "]/d " << system.UnknownName(col) << " (n = " << n << ")";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllSystems, DaeSystemJacobian,
    ::testing::Values(Case{"chapter", ContactForm::kChapter, ConstraintLevel::kVelocity, false, false},
                      Case{"chapter", ContactForm::kChapter, ConstraintLevel::kVelocity, false, true},
                      Case{"chapter", ContactForm::kChapter, ConstraintLevel::kPosition, false, false},
                      Case{"chapter", ContactForm::kClosedForm, ConstraintLevel::kVelocity, false, false},
                      Case{"chapter", ContactForm::kClosedForm, ConstraintLevel::kPosition, false, true},
                      Case{"chapter", ContactForm::kChapter, ConstraintLevel::kVelocity, true, false},
                      Case{"chapter", ContactForm::kClosedForm, ConstraintLevel::kVelocity, true, true},
                      Case{"anatomical", ContactForm::kChapter, ConstraintLevel::kVelocity, false, false},
                      Case{"anatomical", ContactForm::kClosedForm, ConstraintLevel::kVelocity, false, false},
                      Case{"anatomical", ContactForm::kChapter, ConstraintLevel::kVelocity, true, false},
                      Case{"anatomical", ContactForm::kClosedForm, ConstraintLevel::kVelocity, true, true}),
    [](const ::testing::TestParamInfo<Case>& info) { return CaseName(info.param); });

// InitialValues' contact-coordinate rates ċ keep the contact-coordinate rows (x, y of Eqs.
// 1.8 and 1.13) stationary along (q̇, ċ): the rows' derivative along ẏ, from the Jet<24>
// Jacobian (an independent path), vanishes at a consistent state.
TEST(DaeSystem, InitialContactCoordinateRatesKeepTheRowsStationary) {
  const Scene& scene = ChapterScene();
  for (const Scene* sc : {&scene, &AnatomicalScene()}) {
    MechanicalState s = ConsistentInitialize(sc->model, sc->initial, {0, 1}, ConsistentInitOptions{}, nullptr);
    s.qd << 0.01, -0.03, 0.02, 2.0, -0.3, 0.5;  // moving (the rows need not vanish in y)
    s.ligament_branch = LigamentBranchesAt(sc->model, s.q, s.qd);
    for (bool ggl : {false, true}) {
      DaeSystem system(sc->model, ContactForm::kChapter, ConstraintLevel::kVelocity, ggl);
      system.SetPhase(s.active, s.contact, s.ligament_branch);
      const int n = system.size();
      std::vector<double> y(n), yp(n), J(n * n);
      system.InitialValues(s, y.data(), yp.data());
      ASSERT_TRUE(system.JacobianByJets(s.t, 0.0, y.data(), yp.data(), J.data()));
      for (int c = 0; c < 2; ++c) {
        const int row0 = system.FirstContactRow(c);
        const std::vector<int> rows = ggl ? std::vector<int>{row0, row0 + 1, row0 + 2, row0 + 3}
                                          : std::vector<int>{row0, row0 + 1, row0 + 3, row0 + 4};
        for (int r : rows) {
          double rate = 0.0, scale = 0.0;
          for (int j = 0; j < system.NormalIndex(0); ++j) {
            if (j >= 6 && j < 12) continue;  // the rows read q and c only
            rate += J[r + n * j] * yp[j];
            scale += std::abs(J[r + n * j] * yp[j]);
          }
          EXPECT_LE(std::abs(rate), 1e-12 * (1.0 + scale)) << "row " << r << (ggl ? " (GGL)" : "");
          EXPECT_GT(scale, 1e-6) << "the state does not move the row: the check would be empty";
        }
      }
    }
  }
}

// RegularChartContactPartials (closed-form derivatives over (q, c_i) of one contact's
// regular-chart residuals and G) against the second engine, ChapterContactResiduals and
// ContactConstraintRow evaluated on PoseWithCoordinateDerivatives' Jet pose with Jet
// coordinates: values and all ten derivative slots agree to round-off, on both scenes'
// surfaces (sphere caps on planes; the anatomical general surfaces), at poses and contact
// coordinates moved away from the consistent start so no term vanishes by symmetry.
TEST(RegularChartContactPartials, EqualTheJetDerivative) {
  std::mt19937 rng(25);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Scene* sc : {&ChapterScene(), &AnatomicalScene()}) {
    const MechanicalState s0 = ConsistentInitialize(sc->model, sc->initial, {0, 1}, ConsistentInitOptions{}, nullptr);
    for (int trial = 0; trial < 8; ++trial) {
      Vector6d q = s0.q;
      for (int i = 0; i < 3; ++i) q(i) += MmToM(0.5) * u(rng);
      for (int i = 3; i < 6; ++i) q(i) += DegToRad(trial == 0 ? 0.0 : 15.0) * u(rng);
      const EulerAngleTrig<double> trig = EulerAngleTrigOf(q);
      const Pose pose = PoseFromCoordinates(q, trig);
      Matrix3d dR[3];
      RotationPartials(trig, dR);
      const PoseTpl<ContactJet> pose_jet = PoseWithCoordinateDerivatives<kContactJetSize>(q);
      for (int c : s0.active) {
        const ContactPair& pair = sc->model.contacts[c];
        ASSERT_EQ(s0.contact[c].chart, ContactChart::kRegular);
        double coords[4];
        ContactJet coords_jet[4];
        for (int j = 0; j < 4; ++j) {
          coords[j] = s0.contact[c].coordinates[j] + 0.02 * MmToM(1.0) * u(rng) * (trial > 0);
          coords_jet[j] = ContactJet(coords[j], 6 + j);
        }
        ContactJet r[5], r_jet[5];
        Eigen::Matrix<ContactJet, 1, 6> G;
        ContactGeometryTpl<ContactJet> geo;
        ASSERT_TRUE(RegularChartContactPartials(pair, pose, dR, coords, r, &G));
        ASSERT_TRUE(ChapterContactResiduals(pair, pose_jet, coords_jet, r_jet, &geo, ContactChart::kRegular));
        const Eigen::Matrix<ContactJet, 1, 6> G_jet = ContactConstraintRow(pose_jet, geo);
        auto expect_equal = [&](const ContactJet& a, const ContactJet& b, const std::string& what) {
          const double scale = std::max(std::abs(b.a), b.v.cwiseAbs().maxCoeff());
          EXPECT_NEAR(a.a, b.a, 1e-13 * (1.0 + scale)) << what << " value";
          for (int j = 0; j < kContactJetSize; ++j) {
            EXPECT_NEAR(a.v[j], b.v[j], 1e-12 * (1.0 + scale)) << what << " slot " << j << " (trial " << trial << ")";
          }
        };
        for (int i = 0; i < 5; ++i) expect_equal(r[i], r_jet[i], "r[" + std::to_string(i) + "]");
        for (int i = 0; i < 6; ++i) expect_equal(G(i), G_jet(i), "G[" + std::to_string(i) + "]");
      }
    }
  }
}

// The free Newton–Euler partials against central differences of the double residual
// NewtonEulerResidual with no contact (k = 0): independent of any Jet.
TEST(FreeNewtonEulerPartials, MatchCentralDifferences) {
  const Scene& scene = ChapterScene();
  const Model& model = scene.model;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d q = scene.initial.q, qd, qdd;
  q(kAlpha) += DegToRad(35.0);
  for (int i = 0; i < 6; ++i) {
    q(i) += (i < 3 ? 2e-3 : 0.05) * u(rng);
    qd(i) = (i < 3 ? 0.1 : 2.0) * u(rng);
    qdd(i) = 10.0 * u(rng);
  }
  const std::vector<signed char> branch = LigamentBranchesAt(model, q, qd);
  Data data(model);
  data.ligament_branch = &branch;
  const double t = 0.04;
  auto r = [&](const Vector6d& q_, const Vector6d& qd_, const Vector6d& qdd_) {
    return NewtonEulerResidual(model, t, q_, qd_, qdd_, PoseFromCoordinates(q_), 0,
                               static_cast<const ContactGeometry*>(nullptr), static_cast<const double*>(nullptr),
                               &data);
  };
  NewtonEulerPartials p;
  FreeNewtonEulerPartials(model, t, q, qd, qdd, data, &p);
  r(q, qd, qdd);  // fills data.ligament_tension
  int tensioned = 0;
  for (double f : data.ligament_tension) tensioned += f > 0.0;
  ASSERT_GE(tensioned, 3) << "too few taut ligaments for the check to mean anything";
  for (int which = 0; which < 3; ++which) {
    const Matrix6d& analytic = which == 0 ? p.d_q : which == 1 ? p.d_qd : p.d_qdd;
    for (int j = 0; j < 6; ++j) {
      const double h = which == 0 ? (j < 3 ? 1e-7 : 1e-6) : 1e-5;
      Vector6d a = which == 0 ? q : which == 1 ? qd : qdd, b = a;
      a(j) += h;
      b(j) -= h;
      const Vector6d fd = which == 0   ? Vector6d((r(a, qd, qdd) - r(b, qd, qdd)) / (2 * h))
                          : which == 1 ? Vector6d((r(q, a, qdd) - r(q, b, qdd)) / (2 * h))
                                       : Vector6d((r(q, qd, a) - r(q, qd, b)) / (2 * h));
      for (int i = 0; i < 6; ++i) {
        EXPECT_NEAR(analytic(i, j), fd(i), 1e-6 * (1.0 + std::abs(fd(i))))
            << "block " << which << " (q, qd, qdd), row " << i << ", column " << j;
      }
    }
  }
}

}  // namespace
}  // namespace kneedyn
