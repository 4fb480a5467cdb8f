// Tests of the tibio-femoral contact (solver/contact.hpp; chapter Eqs. 1.6–1.13, docs/model.md §4).
//
// Validates, on the chapter's knee (scene chapter_impact.yaml) at random poses near the
// reference pose:
//  - the chapter form (ChapterContactResiduals, solved here by Newton with a Jet Jacobian)
//    and the closed sphere-on-plane form (SphereOnPlaneContact) give the same femoral
//    point, normal and gap; the same tibial point when the gap is closed, and the
//    tibial point offset by the F-z separation e = (0, 0, φ/n_z) when it is not (with a
//    gap the chapter's Eq. 1.8 x, y components put the tibial point vertically below the
//    femoral one, the closed form puts it at the femoral point itself);
//  - at the reference pose both gaps vanish and all five chapter residuals vanish;
//  - the velocity row G against finite differences of the gap, and the acceleration term
//    κ against second differences of the gap;
//  - the contact wrench's moment is point × force.
// Does not validate: contact forces (expected_values_test.cpp), surfaces other than
// sphere-on-plane.
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <array>
#include <cmath>
#include <random>
#include <string>

#include "solver/contact_kinematics.hpp"
#include "tests/test_support.hpp"
#include "solver/error.hpp"
#include "scene/scene.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

const Scene& ChapterScene() {
  static const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  return scene;
}

// Reference pose perturbed by up to ±3° per angle and ±1 mm per R0 component.
Vector6d PerturbedPose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d q = ChapterScene().reference_q;
  for (int i = 0; i < 3; ++i) q(i) += MmToM(1.0) * u(rng);
  for (int i = 3; i < 6; ++i) q(i) += DegToRad(3.0) * u(rng);
  return q;
}

// Starting point for Newton, typed from docs/model.md §6 (the chapter's guesses, mm); the lateral
// tibial guess is not in the chapter: femoral (x, y) minus roughly (x0, y0).
std::array<double, 4> StartGuess(Compartment c) {
  if (c == Compartment::kMedial) {
    return {MmToM(-16.72913866466), MmToM(-18.540280082863), MmToM(-16.980955), MmToM(-12.8)};
  }
  return {MmToM(16.50009371), MmToM(-16.00200022911), MmToM(16.3), MmToM(-10.3)};
}

struct ChapterSolution {
  std::array<double, 4> c{};
  double residual[5] = {0, 0, 0, 0, 0};
  ContactGeometry geometry;
};

// Solves residuals 0, 1 (x, y of Eq. 1.8) and 3, 4 (colinearity, Eq. 1.13) for the four
// contact coordinates at a fixed pose, by Newton with the Jet<double, 4> Jacobian.
ChapterSolution SolveChapterForm(const ContactPair& pair, const Pose& pose,
                                 std::array<double, 4> c) {
  using J = ceres::Jet<double, 4>;
  PoseTpl<J> pose_j;
  pose_j.p_FoTo_F = pose.p_FoTo_F.cast<J>();
  pose_j.R_FT = pose.R_FT.cast<J>();
  const int rows[4] = {0, 1, 3, 4};
  double last_step = 1.0;
  for (int it = 0; it < 50 && last_step > 1e-16; ++it) {
    J cj[4], r[5];
    for (int k = 0; k < 4; ++k) cj[k] = J(c[k], k);
    if (!ChapterContactResiduals(pair, pose_j, cj, r)) {
      ADD_FAILURE() << "surface evaluated outside its domain at Newton iteration " << it;
      break;
    }
    Eigen::Vector4d f;
    Eigen::Matrix4d A;
    for (int i = 0; i < 4; ++i) {
      f(i) = r[rows[i]].a;
      A.row(i) = r[rows[i]].v.transpose();
    }
    const Eigen::Vector4d step = A.fullPivLu().solve(-f);
    for (int k = 0; k < 4; ++k) c[k] += step(k);
    last_step = step.norm();
  }
  ChapterSolution out;
  out.c = c;
  EXPECT_TRUE(ChapterContactResiduals(pair, pose, out.c.data(), out.residual, &out.geometry));
  for (int i : rows) EXPECT_LT(std::abs(out.residual[i]), 1e-14) << "residual " << i;
  return out;
}

// Gap of a sphere on a plane typed from docs/model.md §4: φ = n·(C − R0) − d − r, n = R n̂′.
double GapFromSpec(const SphereOnPlane& sop, const Pose& pose) {
  return (pose.R_FT * sop.normal_T).dot(sop.centre_F - pose.p_FoTo_F) - sop.offset - sop.radius;
}

// Moves x0 and z0 so that both gaps close (φ is linear in R0: φ(R0 + δ) = φ − n·δ).
Vector6d CloseBothGaps(Vector6d q) {
  const Model& model = ChapterScene().model;
  const Pose pose = PoseFromCoordinates(q);
  Eigen::Matrix2d A;
  Eigen::Vector2d b;
  for (int i = 0; i < 2; ++i) {
    const SphereOnPlane& sop = test_support::SopOf(model.contacts[i]);
    const Vector3d n = pose.R_FT * sop.normal_T;
    A(i, 0) = n.x();
    A(i, 1) = n.z();
    b(i) = GapFromSpec(sop, pose);
  }
  const Eigen::Vector2d d = A.fullPivLu().solve(b);
  q(kX0) += d(0);
  q(kZ0) += d(1);
  return q;
}

void ExpectFormsAgree(const ContactPair& pair, const Pose& pose, bool gap_closed) {
  const SphereOnPlane& sop = test_support::SopOf(pair);
  const ContactGeometry closed = SphereOnPlaneContact(sop, pose);
  const ChapterSolution chapter = SolveChapterForm(pair, pose, StartGuess(pair.compartment));
  const ContactGeometry& ch = chapter.geometry;
  const char* name = CompartmentName(pair.compartment);
  EXPECT_LT((ch.point_F - closed.point_F).norm(), 1e-12) << name;
  EXPECT_LT((ch.normal_T - closed.normal_T).norm(), 1e-12) << name;
  EXPECT_NEAR(ch.gap, closed.gap, 1e-12) << name;
  EXPECT_NEAR(closed.gap, GapFromSpec(sop, pose), 1e-15) << name;
  // The chapter's tibial point is on the plane, vertically (F z) below the femoral point:
  // e = Xf − R0 − R X′t = (0, 0, e_z) with n·e = φ.
  const Vector3d n_F = pose.R_FT * sop.normal_T;
  const Vector3d e_F(0.0, 0.0, closed.gap / n_F.z());
  const Vector3d expected_T = closed.point_T - pose.R_FT.transpose() * e_F;
  EXPECT_LT((ch.point_T - expected_T).norm(), 1e-12) << name << ", gap = " << closed.gap;
  EXPECT_NEAR(sop.normal_T.dot(ch.point_T), sop.offset, 1e-14) << name;
  if (gap_closed) {
    EXPECT_NEAR(ch.point_T.x(), closed.point_T.x(), 1e-12) << name;
    EXPECT_NEAR(ch.point_T.y(), closed.point_T.y(), 1e-12) << name;
    EXPECT_NEAR(ch.point_T.z(), closed.point_T.z(), 1e-12) << name;
    EXPECT_LT(std::abs(chapter.residual[2]), 1e-12) << name;
  }
}

TEST(Contact, ChapterAndClosedFormsAgreeAtRandomPoses) {
  const Model& model = ChapterScene().model;
  ASSERT_EQ(model.contacts.size(), 2u);
  std::mt19937 rng(21);
  for (int s = 0; s < 30; ++s) {
    const Pose pose = PoseFromCoordinates(PerturbedPose(rng));
    for (const ContactPair& pair : model.contacts) {
      SphereOnPlane unused;
      ASSERT_TRUE(SphereOnPlaneForm(pair, &unused));
      ExpectFormsAgree(pair, pose, false);
    }
  }
}

TEST(Contact, ChapterAndClosedFormsGiveSameTibialPointWhenInContact) {
  const Model& model = ChapterScene().model;
  std::mt19937 rng(22);
  for (int s = 0; s < 30; ++s) {
    const Pose pose = PoseFromCoordinates(CloseBothGaps(PerturbedPose(rng)));
    for (const ContactPair& pair : model.contacts) {
      EXPECT_NEAR(SphereOnPlaneContact(test_support::SopOf(pair), pose).gap, 0.0, 1e-15);
      ExpectFormsAgree(pair, pose, true);
    }
  }
}

TEST(Contact, ReferencePoseClosesBothGapsAndAllFiveChapterResiduals) {
  const Scene& scene = ChapterScene();
  const Pose pose = PoseFromCoordinates(scene.reference_q);
  for (const ContactPair& pair : scene.model.contacts) {
    const ContactGeometry closed = SphereOnPlaneContact(test_support::SopOf(pair), pose);
    EXPECT_NEAR(closed.gap, 0.0, 1e-12) << CompartmentName(pair.compartment);
    const ChapterSolution chapter = SolveChapterForm(pair, pose, StartGuess(pair.compartment));
    for (int i = 0; i < 5; ++i) {
      EXPECT_LT(std::abs(chapter.residual[i]), 1e-12)
          << CompartmentName(pair.compartment) << " residual " << i;
    }
    EXPECT_LT((chapter.geometry.point_T - closed.point_T).norm(), 1e-12);
    EXPECT_LT((chapter.geometry.point_F - closed.point_F).norm(), 1e-12);
  }
}

TEST(Contact, ChapterResidualsRefuseCoordinatesOutsideTheCondyle) {
  const ContactPair& pair = ChapterScene().model.contacts[0];
  const Pose pose = PoseFromCoordinates(ChapterScene().reference_q);
  const double far[4] = {0.5, 0.5, 0.0, 0.0};
  double r[5];
  EXPECT_FALSE(ChapterContactResiduals(pair, pose, far, r));
}

TEST(ContactConstraintRow, TimesGeneralizedVelocityIsGapRate) {
  const Model& model = ChapterScene().model;
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = 1e-6;
  for (int s = 0; s < 30; ++s) {
    const Vector6d q = PerturbedPose(rng);
    Vector6d qd;
    qd << 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng), 3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng);
    const Pose pose = PoseFromCoordinates(q);
    const Vector6d nu = GeneralizedVelocity(q, qd);
    for (const ContactPair& pair : model.contacts) {
      const SphereOnPlane& sop = test_support::SopOf(pair);
      auto gap_at = [&](double t) {
        return SphereOnPlaneContact(sop, PoseFromCoordinates(Vector6d(q + t * qd))).gap;
      };
      const double fd = (gap_at(h) - gap_at(-h)) / (2 * h);
      const Eigen::Matrix<double, 1, 6> G =
          ContactConstraintRow(pose, SphereOnPlaneContact(sop, pose));
      EXPECT_NEAR(G.dot(nu), fd, 1e-8) << CompartmentName(pair.compartment);
    }
  }
}

TEST(ContactRateTerm, GapSecondDerivativeIsRowTimesAccelerationPlusKappa) {
  const Model& model = ChapterScene().model;
  std::mt19937 rng(24);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = 1e-3;
  for (int s = 0; s < 30; ++s) {
    const Vector6d q = PerturbedPose(rng);
    Vector6d qd, qdd;
    qd << 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng), 3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng);
    qdd << 5.0 * u(rng), 5.0 * u(rng), 5.0 * u(rng), 50.0 * u(rng), 50.0 * u(rng),
        50.0 * u(rng);
    const Pose pose = PoseFromCoordinates(q);
    const Vector6d nu = GeneralizedVelocity(q, qd);
    const Vector6d nu_dot = GeneralizedAcceleration(q, qd, qdd);
    for (const ContactPair& pair : model.contacts) {
      const SphereOnPlane& sop = test_support::SopOf(pair);
      auto gap_at = [&](double t) {
        const Vector6d qt = q + t * qd + 0.5 * t * t * qdd;
        return SphereOnPlaneContact(sop, PoseFromCoordinates(qt)).gap;
      };
      // Fourth-order central second difference.
      const double fd = (-gap_at(2 * h) + 16 * gap_at(h) - 30 * gap_at(0.0) + 16 * gap_at(-h) -
                         gap_at(-2 * h)) /
                        (12 * h * h);
      const double analytic =
          ContactConstraintRow(pose, SphereOnPlaneContact(sop, pose)).dot(nu_dot) +
          ContactRateTerm(pair, q, qd, pose, nu);  // the overload the solvers call
      EXPECT_NEAR(analytic, fd, 1e-6 * (1.0 + std::abs(fd))) << CompartmentName(pair.compartment);
    }
  }
}

TEST(AddContactWrench, MomentIsPointCrossForceInTibialFrame) {
  const Model& model = ChapterScene().model;
  std::mt19937 rng(25);
  for (int s = 0; s < 20; ++s) {
    const Pose pose = PoseFromCoordinates(PerturbedPose(rng));
    for (const ContactPair& pair : model.contacts) {
      const ContactGeometry geo = SphereOnPlaneContact(test_support::SopOf(pair), pose);
      const double N = 150.0 + 10.0 * s;
      const Vector3d f0(1.0, -2.0, 3.0), m0(-0.5, 0.25, 0.125);
      Vector3d force_F = f0, moment_T = m0;
      AddContactWrench(pose, geo, N, &force_F, &moment_T);
      const Vector3d df_F = force_F - f0;
      // −N n applied at the tibial point: magnitude N, pushing the tibia away from the femur.
      EXPECT_NEAR(df_F.norm(), N, 1e-12 * N);
      EXPECT_LT((df_F + N * (pose.R_FT * test_support::SopOf(pair).normal_T)).norm(), 1e-12 * N);
      const Vector3d df_T = pose.R_FT.transpose() * df_F;
      EXPECT_LT(((moment_T - m0) - geo.point_T.cross(df_T)).norm(), 1e-12 * N);
    }
  }
}

// Two parallel planes have no isolated contact point (the 4×4 system is singular).
TEST(RequireContactKinematics, RefusesAPairWithoutContactPointNamingTheCompartment) {
  ContactPair pair;
  pair.compartment = Compartment::kLateral;
  pair.femoral_surface = std::make_shared<PlaneSurface>(0.0, 0.0, 0.0);
  pair.tibial_surface = std::make_shared<PlaneSurface>(0.0, 0.0, 0.2);
  try {
    (void)RequireContactKinematics(pair, PoseFromCoordinates(ChapterScene().reference_q), "MyFormulation");
    ADD_FAILURE() << "no exception";
  } catch (const SolverError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("lateral"), std::string::npos) << what;
    EXPECT_NE(what.find("MyFormulation"), std::string::npos) << what;
  }
  EXPECT_NO_THROW((void)RequireContactKinematics(ChapterScene().model.contacts[0],
                                                 PoseFromCoordinates(ChapterScene().reference_q), "x"));
}

}  // namespace
}  // namespace kneedyn
