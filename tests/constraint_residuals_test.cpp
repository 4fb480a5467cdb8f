// Tests of the constraint residuals (solver/constraint_residuals.hpp) and the
// physical-sample checks (solver/sample_checks.hpp).
//
// Validates:
//  - φ and φ̇ vanish (to the initialization's tolerance) on a state built by the
//    consistent initialization with a non-zero initial velocity, for both contact forms;
//  - away from consistency, φ equals the sphere-on-plane formula n_F·(C − R0) − d − r
//    written from the surfaces' data, and φ̇ a central difference of φ along q + t q̇;
//  - the sample checks refuse a non-finite state and a gap beyond 1 mm, accept a contact
//    point past the condyle's equator (outside the chapter's lower-hemisphere height field,
//    inside the sphere's regular chart), and refuse one beyond the regular chart (|v| ≥ 170°,
//    the top of the sphere), naming the femoral surface.
// Does not validate: the chapter-form residuals (contact_test.cpp).
#include <gtest/gtest.h>

#include <cmath>

#include "solver/consistent_init.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/contact_kinematics.hpp"
#include "solver/ellipsoid_cap.hpp"
#include "solver/error.hpp"
#include "solver/sample_checks.hpp"
#include "solver/units.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;
using test_support::SopOf;

Scene MovingChapterScene() {
  Scene scene = ChapterScene();
  scene.initial.qd << 0.01, -0.02, 0.0, 1.5, 0.3, -0.4;
  scene.initial.held_velocities = {kAlpha};
  return scene;
}

class ResidualsOnConsistentState : public ::testing::TestWithParam<ContactForm> {};

TEST_P(ResidualsOnConsistentState, VanishForEveryActiveContact) {
  const Scene scene = MovingChapterScene();
  ConsistentInitOptions o;
  o.form = GetParam();
  InitReport report;
  const MechanicalState s = ConsistentInitialize(scene.model, scene.initial, {0, 1}, o, &report);
  ASSERT_GT(std::abs(s.qd(kAlpha)), 1.0) << "the state must move for φ̇ = 0 to mean something";
  std::vector<double> gap, rate;
  ConstraintResiduals(scene.model, s, &gap, &rate);
  ASSERT_EQ(gap.size(), scene.model.contacts.size());
  for (int c : {0, 1}) {
    EXPECT_NEAR(gap[c], 0.0, 1e-10) << "contact " << c << " (m)";
    EXPECT_NEAR(rate[c], 0.0, 1e-10) << "contact " << c << " (m/s)";
  }
  double max_gap = -1.0, max_rate = -1.0;
  MaxActiveConstraintResiduals(scene.model, s, &max_gap, &max_rate);
  EXPECT_LE(max_gap, 1e-10);
  EXPECT_LE(max_rate, 1e-10);
  EXPECT_GE(max_gap, 0.0);
}

INSTANTIATE_TEST_SUITE_P(BothForms, ResidualsOnConsistentState,
                         ::testing::Values(ContactForm::kChapter, ContactForm::kClosedForm));

TEST(ConstraintResiduals, MatchSphereOnPlaneFormulaAndDifferenceOfGap) {
  const Model& model = ChapterScene().model;
  MechanicalState s;
  s.q = ChapterScene().initial.q;
  s.q(kZ0) += 0.7e-3;  // separated by about 0.7 mm
  s.q(kAlpha) += 0.1;
  s.qd << 0.02, -0.01, 0.05, 1.0, -0.2, 0.3;
  s.active = {0, 1};
  std::vector<double> gap, rate;
  ConstraintResiduals(model, s, &gap, &rate);
  auto phi = [&](int c, const Vector6d& q) {
    const SphereOnPlane sop = SopOf(model.contacts[c]);
    const Pose pose = PoseFromCoordinates(q);
    return (pose.R_FT * sop.normal_T).dot(sop.centre_F - pose.p_FoTo_F) - sop.offset - sop.radius;
  };
  const double h = 1e-6;
  for (int c : {0, 1}) {
    EXPECT_NEAR(gap[c], phi(c, s.q), 1e-15) << c;
    EXPECT_NEAR(rate[c], (phi(c, s.q + h * s.qd) - phi(c, s.q - h * s.qd)) / (2 * h), 1e-9) << c;
  }
  double max_gap = 0.0, max_rate = 0.0;
  MaxActiveConstraintResiduals(model, s, &max_gap, &max_rate);
  EXPECT_EQ(max_gap, std::max(std::abs(gap[0]), std::abs(gap[1])));
  EXPECT_EQ(max_rate, std::max(std::abs(rate[0]), std::abs(rate[1])));
}

// A state with only `contact` active, rotated by flexion `alpha` and translated along the
// contact normal so that its gap is zero.
MechanicalState ClosedAt(const Model& model, int contact, double alpha) {
  MechanicalState s;
  s.q = ChapterScene().initial.q;
  s.q(kAlpha) = alpha;
  s.active = {contact};
  s.contact.resize(model.contacts.size());
  for (int it = 0; it < 3; ++it) {
    const Pose pose = PoseFromCoordinates(s.q);
    ContactGeometry g;
    EXPECT_TRUE(ContactKinematics(model.contacts[contact], pose, &g));
    s.q.head<3>() += g.gap * (pose.R_FT * g.normal_T);
  }
  return s;
}

std::string CheckMessage(const Model& model, const MechanicalState& s) {
  try {
    CheckSampleIsPhysical(model, s);
  } catch (const SolverError& e) {
    return e.what();
  }
  return "";
}

TEST(SampleChecks, RefuseNonFiniteStateAndLargeViolation) {
  const Model& model = ChapterScene().model;
  MechanicalState s = ClosedAt(model, 0, DegToRad(20.0));
  EXPECT_EQ(CheckMessage(model, s), "");
  MechanicalState bad = s;
  bad.qd(kAlpha) = std::nan("");
  EXPECT_NE(CheckMessage(model, bad).find("non-finite state"), std::string::npos);
  bad = s;
  bad.q(kZ0) -= 2.0e-3;  // ≈ 2 mm penetration
  EXPECT_NE(CheckMessage(model, bad).find("medial contact constraint is violated"), std::string::npos)
      << CheckMessage(model, bad);
}

TEST(SampleChecks, ContactPastTheEquatorIsOnTheSurfaceUntilTheRegularChartEnds) {
  const Model& model = ChapterScene().model;
  const SphereOnPlane sop = SopOf(model.contacts[0]);
  // The sphere cap's regular chart (height_field.hpp): P = C + r (sin u, cos u sin v,
  // −cos u cos v), |u| < 80°, |v| < 170°. Angles of the femoral contact point, and its
  // height above the centre in radii (> 0: past the equator, off the chapter's height field).
  struct Where { double u_deg, v_deg, height; };
  auto where = [&](const MechanicalState& s) {
    ContactGeometry g;
    EXPECT_TRUE(ContactKinematics(model.contacts[0], PoseFromCoordinates(s.q), &g));
    const Vector3d d = (g.point_F - sop.centre_F) / sop.radius;
    return Where{RadToDeg(std::asin(d.x())), RadToDeg(std::atan2(d.y(), -d.z())), d.z()};
  };
  int past_equator = 0, beyond_chart = 0;
  for (double deg = -180.0; deg <= 180.0; deg += 1.0) {
    const MechanicalState s = ClosedAt(model, 0, DegToRad(deg));
    const Where w = where(s);
    ASSERT_LT(std::abs(w.u_deg), 79.0);
    const std::string msg = CheckMessage(model, s);
    if (w.height > 0.05 && std::abs(w.v_deg) < 169.5) {
      ++past_equator;
      EXPECT_EQ(msg, "") << "flexion " << deg << " deg, v = " << w.v_deg << " deg";
    }
    if (std::abs(w.v_deg) > 170.5) {
      ++beyond_chart;
      EXPECT_NE(msg.find("medial contact point left the femoral surface (sphere_cap"), std::string::npos)
          << "flexion " << deg << " deg, v = " << w.v_deg << " deg: " << msg;
    }
  }
  EXPECT_GT(past_equator, 50);
  EXPECT_GT(beyond_chart, 3);
}

// Ellipsoidal condyle on the chapter's plateau plane (general local solve, no closed form):
// the check accepts contact points the lower-cap height field does not cover (past the
// equator its height at (x, y) is another point) as long as the regular charts hold them.
TEST(SampleChecks, EllipsoidCapPastTheHeightFieldIsAccepted) {
  Model model = ChapterScene().model;
  const SphereOnPlane sop = SopOf(model.contacts[0]);
  model.contacts[0].femoral_surface = std::make_shared<EllipsoidCap>(
      sop.centre_F, Vector3d(0.020, 0.024, 0.021), Matrix3d::Identity());
  model.contacts.resize(1);
  SphereOnPlane unused;
  ASSERT_FALSE(SphereOnPlaneForm(model.contacts[0], &unused)) << "must take the general solve";
  MechanicalState s;
  s.q = ChapterScene().initial.q;
  s.active = {0};
  s.contact.resize(1);
  int off_height_field = 0, on_height_field = 0;
  for (double deg = RadToDeg(s.q(kAlpha)); deg <= 160.0; deg += 2.0) {  // continuation in flexion
    s.q(kAlpha) = DegToRad(deg);
    ContactGeometry g;
    bool closed = false;
    for (int it = 0; it < 20 && !closed; ++it) {  // close the gap along the normal
      const Pose pose = PoseFromCoordinates(s.q);
      if (!ContactKinematics(model.contacts[0], pose, &g)) break;
      s.q.head<3>() += g.gap * (pose.R_FT * g.normal_T);
      closed = std::abs(g.gap) < 1e-12;
    }
    ASSERT_TRUE(closed) << "flexion " << deg << " deg";
    HeightSample hs;
    // On the chapter's chart when the lower cap's height at (x, y) is the point's z.
    const bool on_hf = model.contacts[0].femoral_surface->Evaluate(g.point_F.x(), g.point_F.y(), &hs) &&
                       std::abs(hs.value - g.point_F.z()) < 1e-9;
    (on_hf ? on_height_field : off_height_field)++;
    EXPECT_EQ(CheckMessage(model, s), "") << "flexion " << deg << " deg";
  }
  EXPECT_GT(on_height_field, 5);
  EXPECT_GT(off_height_field, 5);
}

}  // namespace
}  // namespace kneedyn
