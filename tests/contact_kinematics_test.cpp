// Tests of the one contact-kinematics interface (solver/contact_kinematics.hpp) for every
// surface pair kneedyn has.
//
// Validates, at random poses around the chapter's reference pose (gaps up to ~±1 mm):
//  - the sphere-on-plane closed form equals the general local solve: the same sphere and
//    plane wrapped in a surface class that hides SphereForm/PlaneForm take the general path
//    (the case that used to throw in ConsistentInitialize);
//  - for every pair: the Jet derivative of the gap is G B (chain rule, ∂φ/∂q), G ν matches
//    a central difference of φ along q + t q̇, and G ν̇ + κ a fourth-order second
//    difference of φ along q + t q̇ + t²/2 q̈ (independent: only gaps are differenced);
//  - the solved points satisfy the contact conditions: the femoral and tibial points lie on
//    their surfaces, the separation is along the normal, the normals are parallel.
// Does not validate: contact forces (expected_values_test.cpp) or the chapter form
// (contact_test.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "solver/contact_kinematics.hpp"
#include "solver/ellipsoid_cap.hpp"
#include "solver/error.hpp"
#include "solver/polynomial_surface.hpp"
#include "solver/units.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

using test_support::ChapterScene;

// Forwards everything except the closed-form queries: forces the general solve.
class Opaque final : public HeightField {
 public:
  explicit Opaque(std::shared_ptr<const HeightField> s) : s_(std::move(s)) {}
  bool Evaluate(double x, double y, HeightSample* h) const override { return s_->Evaluate(x, y, h); }
  std::string Describe() const override { return "opaque " + s_->Describe(); }
  bool EvaluateChart(double u, double v, ChartSample* c) const override {
    return s_->EvaluateChart(u, v, c);
  }
  void ChartCoordinates(const Vector3d& p, double uv[2]) const override {
    s_->ChartCoordinates(p, uv);
  }
  bool PointWithNormal(const Vector3d& n, double uv[2]) const override {
    return s_->PointWithNormal(n, uv);
  }

 private:
  std::shared_ptr<const HeightField> s_;
};

ContactPair OpaquePair(const ContactPair& p) {
  ContactPair out = p;
  out.femoral_surface = std::make_shared<Opaque>(p.femoral_surface);
  out.tibial_surface = std::make_shared<Opaque>(p.tibial_surface);
  return out;
}

Vector6d PerturbedPose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d q = ChapterScene().reference_q;
  for (int i = 0; i < 3; ++i) q(i) += MmToM(1.0) * u(rng);
  for (int i = 3; i < 6; ++i) q(i) += DegToRad(3.0) * u(rng);
  q(kAlpha) += DegToRad(40.0) * (0.5 + 0.5 * u(rng));  // up to 40° of flexion
  return q;
}

struct NamedPair {
  std::string name;
  ContactPair pair;
};

// Every surface pair under test, at the chapter's compartments.
std::vector<NamedPair> AllPairs() {
  std::vector<NamedPair> out;
  for (const ContactPair& p : ChapterScene().model.contacts) {
    const std::string c = CompartmentName(p.compartment);
    out.push_back({"sphere_on_plane_" + c, p});
    out.push_back({"opaque_sphere_on_plane_" + c, OpaquePair(p)});
  }
  // The anatomical shapes of reference-data/scenes/anatomical_surfaces.yaml, in SI.
  const auto* med = &ChapterScene().model.contacts[0];
  const auto* lat = &ChapterScene().model.contacts[1];
  const Matrix3d Qm = Eigen::AngleAxisd(DegToRad(5.0), Vector3d::UnitZ()).toRotationMatrix();
  const Matrix3d Ql = Eigen::AngleAxisd(DegToRad(-5.0), Vector3d::UnitZ()).toRotationMatrix();
  auto ell_m = std::make_shared<EllipsoidCap>(Vector3d(-23.75, -18.0, 12.0) * 1e-3,
                                              Vector3d(20.0, 24.0, 21.0) * 1e-3, Qm);
  auto ell_l = std::make_shared<EllipsoidCap>(Vector3d(23.0, -16.0, 11.5) * 1e-3,
                                              Vector3d(19.0, 23.0, 20.0) * 1e-3, Ql);
  double cm[5][5] = {}, cl[5][5] = {};
  cm[1][0] = 0.358;
  cm[2][0] = cm[0][2] = 8.333;   // 1/m: radius 60 mm
  cm[4][0] = cm[0][4] = 1.0e3;   // 1/m^3
  cl[1][0] = -0.341;
  cl[2][0] = cl[0][2] = -6.25;
  cl[2][2] = -1.0e2;
  auto poly_m = std::make_shared<PolynomialSurface>(Vector3d(-17.0, -12.8, 206.914) * 1e-3, 0.0, cm);
  auto poly_l = std::make_shared<PolynomialSurface>(Vector3d(16.3, -10.3, 207.3417) * 1e-3,
                                                    DegToRad(10.0), cl);
  auto make = [](const ContactPair* base, std::shared_ptr<const HeightField> f,
                 std::shared_ptr<const HeightField> t) {
    ContactPair p = *base;
    p.femoral_surface = std::move(f);
    p.tibial_surface = std::move(t);
    return p;
  };
  out.push_back({"ellipsoid_on_polynomial_medial", make(med, ell_m, poly_m)});
  out.push_back({"ellipsoid_on_polynomial_lateral", make(lat, ell_l, poly_l)});
  out.push_back({"ellipsoid_on_plane_medial", make(med, ell_m, med->tibial_surface)});
  out.push_back({"sphere_on_polynomial_lateral", make(lat, lat->femoral_surface, poly_l)});
  return out;
}

// Every surface's two charts: derivatives against central differences, and the regular
// chart's inverse (ChartCoordinates) returns the height-field chart's point.
TEST(Surfaces, ChartDerivativesMatchDifferencesAndChartsAgree) {
  std::mt19937 rng(30);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // (surface, spread of the sampled chart coordinates around the chart origin: rad for the
  // femoral angle charts, m for the tibial height-field charts).
  std::vector<std::pair<std::shared_ptr<const HeightField>, double>> surfaces;
  for (const NamedPair& np : AllPairs()) {
    surfaces.push_back({np.pair.femoral_surface, 0.6});
    surfaces.push_back({np.pair.tibial_surface, 0.03});
  }
  const double h = 1e-6;
  for (const auto& [surf, spread] : surfaces) {
    const std::string name = surf->Describe();
    for (int s = 0; s < 10; ++s) {
      const double uv[2] = {spread * u(rng), spread * u(rng)};
      ChartSample c, cp, cm;
      ASSERT_TRUE(surf->EvaluateChart(uv[0], uv[1], &c)) << name;
      for (int dir = 0; dir < 2; ++dir) {
        const double du = dir == 0 ? h : 0.0, dv = dir == 0 ? 0.0 : h;
        ASSERT_TRUE(surf->EvaluateChart(uv[0] + du, uv[1] + dv, &cp)) << name;
        ASSERT_TRUE(surf->EvaluateChart(uv[0] - du, uv[1] - dv, &cm)) << name;
        const Vector3d dp = (cp.p - cm.p) / (2 * h);
        const Vector3d dpu = (cp.p_u - cm.p_u) / (2 * h), dpv = (cp.p_v - cm.p_v) / (2 * h);
        const double scale = 1.0 + c.p_u.norm() + c.p_v.norm();
        EXPECT_LT((dp - (dir == 0 ? c.p_u : c.p_v)).norm(), 1e-8 * scale) << name;
        EXPECT_LT((dpu - (dir == 0 ? c.p_uu : c.p_uv)).norm(), 1e-6 * scale) << name;
        EXPECT_LT((dpv - (dir == 0 ? c.p_uv : c.p_vv)).norm(), 1e-6 * scale) << name;
      }
      // Orientation: P_u × P_v points to +z near the contact regions.
      EXPECT_GT(c.p_u.cross(c.p_v).z(), 0.0) << name;
      // Inverse chart.
      double back[2];
      surf->ChartCoordinates(c.p, back);
      EXPECT_NEAR(back[0], uv[0], 1e-12) << name;
      EXPECT_NEAR(back[1], uv[1], 1e-12) << name;
      // Height-field chart at the same point: same height, gradient and Hessian by differences.
      HeightSample hs, hx, hy;
      ASSERT_TRUE(surf->Evaluate(c.p.x(), c.p.y(), &hs)) << name;
      EXPECT_NEAR(hs.value, c.p.z(), 1e-14) << name;
      ASSERT_TRUE(surf->Evaluate(c.p.x() + h, c.p.y(), &hx));
      ASSERT_TRUE(surf->Evaluate(c.p.x(), c.p.y() + h, &hy));
      HeightSample mx, my;
      ASSERT_TRUE(surf->Evaluate(c.p.x() - h, c.p.y(), &mx));
      ASSERT_TRUE(surf->Evaluate(c.p.x(), c.p.y() - h, &my));
      EXPECT_NEAR(hs.gradient[0], (hx.value - mx.value) / (2 * h), 1e-8) << name;
      EXPECT_NEAR(hs.gradient[1], (hy.value - my.value) / (2 * h), 1e-8) << name;
      EXPECT_NEAR(hs.hessian[0], (hx.gradient[0] - mx.gradient[0]) / (2 * h), 1e-5 * (1 + std::abs(hs.hessian[0]))) << name;
      EXPECT_NEAR(hs.hessian[1], (hy.gradient[0] - my.gradient[0]) / (2 * h), 1e-5 * (1 + std::abs(hs.hessian[1]))) << name;
      EXPECT_NEAR(hs.hessian[2], (hy.gradient[1] - my.gradient[1]) / (2 * h), 1e-5 * (1 + std::abs(hs.hessian[2]))) << name;
    }
  }
}

double GapAt(const ContactPair& pair, const Vector6d& q) {
  return RequireContactKinematics(pair, PoseFromCoordinates(q), "GapAt").gap;
}

TEST(ContactKinematics, ClosedFormEqualsGeneralSolve) {
  std::mt19937 rng(31);
  for (int s = 0; s < 40; ++s) {
    const Vector6d q = PerturbedPose(rng);
    const Pose pose = PoseFromCoordinates(q);
    Vector6d qd;
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    qd << 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng), 3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng);
    for (const ContactPair& pair : ChapterScene().model.contacts) {
      const ContactPair general = OpaquePair(pair);
      const ContactGeometry a = RequireContactKinematics(pair, pose, "closed");
      const ContactGeometry b = RequireContactKinematics(general, pose, "general");
      const std::string where = StrCat(CompartmentName(pair.compartment), " sample ", s);
      EXPECT_NEAR(a.gap, b.gap, 1e-15) << where;
      // The MDE chart's affine form of the same gap (h − n_F · R0) against the general solve.
      SphereOnPlane sop;
      ASSERT_TRUE(SphereOnPlaneForm(pair, &sop)) << where;
      const Vector3d n_F = pose.R_FT * sop.normal_T;
      EXPECT_NEAR(SphereOnPlaneClosingHeight(sop, n_F) - n_F.dot(pose.p_FoTo_F), b.gap, 1e-15) << where;
      EXPECT_LT((a.point_F - b.point_F).norm(), 1e-14) << where;
      EXPECT_LT((a.normal_T - b.normal_T).norm(), 1e-13) << where;
      // The closed form reports the femoral point in T; the general solve the tibial surface
      // point, φ n′ below it (the same line of action).
      EXPECT_LT((a.point_T - a.gap * a.normal_T - b.point_T).norm(), 1e-14) << where;
      EXPECT_LT((ContactConstraintRow(pose, a) - ContactConstraintRow(pose, b)).norm(), 1e-13) << where;
      const double ka = ContactRateTerm(pair, q, qd), kb = ContactRateTerm(general, q, qd);
      EXPECT_NEAR(ka, kb, 1e-9 * (1.0 + std::abs(ka))) << where;
    }
  }
}

TEST(ContactKinematics, SolvedPointsSatisfyTheContactConditions) {
  std::mt19937 rng(32);
  for (const NamedPair& np : AllPairs()) {
    for (int s = 0; s < 20; ++s) {
      const Pose pose = PoseFromCoordinates(PerturbedPose(rng));
      double chart[4];
      const ContactGeometry g = RequireContactKinematics(np.pair, pose, "test", chart);
      ChartSample f, t;
      ASSERT_TRUE(np.pair.femoral_surface->EvaluateChart(chart[0], chart[1], &f)) << np.name;
      ASSERT_TRUE(np.pair.tibial_surface->EvaluateChart(chart[2], chart[3], &t)) << np.name;
      const Vector3d n_F = pose.R_FT * g.normal_T;
      const Vector3d nf = f.p_u.cross(f.p_v).normalized();
      EXPECT_LT((nf - n_F).norm(), 1e-12) << np.name << ": normals parallel, same sense";
      EXPECT_LT((f.p - g.point_F).norm(), 1e-15) << np.name;
      const Vector3d d = g.point_F - pose.PointInF(t.p);
      EXPECT_LT((d - g.gap * n_F).norm(), 1e-15) << np.name << ": separation along the normal";
      EXPECT_LT((g.point_T - t.p).cross(g.normal_T).norm(), 1e-15) << np.name << ": on the line of action";
      EXPECT_TRUE(std::isfinite(g.gap)) << np.name;
    }
  }
}

TEST(ContactKinematics, JetGapDerivativeIsRowTimesB) {
  std::mt19937 rng(33);
  using J6 = ceres::Jet<double, 6>;
  for (const NamedPair& np : AllPairs()) {
    for (int s = 0; s < 10; ++s) {
      const Vector6d q = PerturbedPose(rng);
      Vector6<J6> qj;
      for (int i = 0; i < 6; ++i) qj(i) = J6(q(i), i);
      ContactGeometryTpl<J6> gj;
      ASSERT_TRUE(ContactKinematics(np.pair, PoseFromCoordinates(qj), &gj)) << np.name;
      const Pose pose = PoseFromCoordinates(q);
      Matrix6d B = Matrix6d::Identity();
      B.bottomRightCorner<3, 3>() = AngularVelocityMap(q(kBeta), q(kGamma));
      const Eigen::Matrix<double, 1, 6> GB =
          ContactConstraintRow(pose, RequireContactKinematics(np.pair, pose, "t")) * B;
      for (int i = 0; i < 6; ++i) {
        EXPECT_NEAR(gj.gap.v(i), GB(i), 1e-12 * (1.0 + std::abs(GB(i)))) << np.name << " q" << i;
      }
    }
  }
}

TEST(ContactKinematics, RowAndRateTermMatchDifferencesOfTheGap) {
  std::mt19937 rng(34);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const NamedPair& np : AllPairs()) {
    for (int s = 0; s < 10; ++s) {
      const Vector6d q = PerturbedPose(rng);
      Vector6d qd, qdd;
      qd << 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng), 3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng);
      qdd << 5.0 * u(rng), 5.0 * u(rng), 5.0 * u(rng), 50.0 * u(rng), 50.0 * u(rng), 50.0 * u(rng);
      const Pose pose = PoseFromCoordinates(q);
      const Vector6d nu = GeneralizedVelocity(q, qd);
      const Vector6d nu_dot = GeneralizedAcceleration(q, qd, qdd);
      const ContactGeometry g = RequireContactKinematics(np.pair, pose, "t");
      const Eigen::Matrix<double, 1, 6> G = ContactConstraintRow(pose, g);
      const double h1 = 1e-6;
      const double fd1 = (GapAt(np.pair, q + h1 * qd) - GapAt(np.pair, q - h1 * qd)) / (2 * h1);
      EXPECT_NEAR(G.dot(nu), fd1, 1e-8) << np.name;
      const double h = 5e-4;  // s: fourth-order truncation ~h⁴ well below the tolerance
      auto gap = [&](double t) { return GapAt(np.pair, q + t * qd + 0.5 * t * t * qdd); };
      const double fd2 =
          (-gap(2 * h) + 16 * gap(h) - 30 * gap(0.0) + 16 * gap(-h) - gap(-2 * h)) / (12 * h * h);
      const double analytic = G.dot(nu_dot) + ContactRateTerm(np.pair, q, qd);
      EXPECT_NEAR(analytic, fd2, 1e-6 * (1.0 + std::abs(fd2))) << np.name;
    }
  }
}

// A surface refused at construction says which input and what value (before: "centre and
// orientation must be finite and the orientation a rotation", "origin and rotation must be
// finite", without either).
TEST(Surfaces, RefusalsNameTheInputAndItsValue) {
  const auto message = [](const std::function<void()>& make) {
    try {
      make();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no InputError");
  };
  Matrix3d sheared = Matrix3d::Identity();
  sheared(0, 1) = 0.1;
  const std::string shear = message([&] { EllipsoidCap(Vector3d::Zero(), Vector3d::Ones(), sheared); });
  EXPECT_NE(shear.find("orientation: det = 1"), std::string::npos) << shear;
  EXPECT_NE(shear.find("|RᵀR − I| = 0.1"), std::string::npos) << shear;
  const std::string centre = message([&] { EllipsoidCap(Vector3d(0.0, NAN, 0.0), Vector3d::Ones(), Matrix3d::Identity()); });
  EXPECT_NE(centre.find("centre = (0, nan, 0) m"), std::string::npos) << centre;
  const double zero[PolynomialSurface::kMaxDegree + 1][PolynomialSurface::kMaxDegree + 1] = {};
  const std::string rotation = message([&] { PolynomialSurface(Vector3d::Zero(), INFINITY, zero); });
  EXPECT_NE(rotation.find("rotation_z = inf rad"), std::string::npos) << rotation;
}

}  // namespace
}  // namespace kneedyn
