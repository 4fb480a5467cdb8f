// Tests of the articular height fields (solver/height_field.hpp; chapter Eqs. 1.4, 1.5,
// docs/model.md §3).
//
// Validates: SphereCap value lies on the sphere, its gradient and Hessian against central
// finite differences inside the footprint, refusal outside the footprint and on the rim;
// PlaneSurface normal and offset against points on the plane; the Jet lifting of
// EvaluateHeight (chain rule) against finite differences along the Jet directions.
// Does not validate: the scene factory that builds surfaces (scene_test.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "solver/error.hpp"
#include "solver/height_field.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

// The chapter's medial condyle (docs/model.md §3), in metres.
const Vector3d kMedialCentre(-0.02375, -0.018, 0.012);
constexpr double kMedialRadius = 0.021;

// A point strictly inside the footprint, at most `fraction` of the radius from the axis.
void RandomFootprintPoint(std::mt19937& rng, const Vector3d& c, double r, double fraction,
                          double* x, double* y) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double rho = fraction * r * std::sqrt(u(rng));
  const double theta = 2.0 * kPi * u(rng);
  *x = c.x() + rho * std::cos(theta);
  *y = c.y() + rho * std::sin(theta);
}

HeightSample Eval(const HeightField& s, double x, double y) {
  HeightSample out;
  EXPECT_TRUE(s.Evaluate(x, y, &out)) << "at (" << x << ", " << y << ")";
  return out;
}

TEST(SphereCap, ValueIsOnTheLowerHemisphere) {
  const SphereCap cap(kMedialCentre, kMedialRadius);
  std::mt19937 rng(11);
  for (int s = 0; s < 100; ++s) {
    double x, y;
    RandomFootprintPoint(rng, kMedialCentre, kMedialRadius, 0.95, &x, &y);
    const HeightSample hs = Eval(cap, x, y);
    const Vector3d p(x, y, hs.value);
    EXPECT_NEAR((p - kMedialCentre).norm(), kMedialRadius, 1e-15);
    EXPECT_LT(hs.value, kMedialCentre.z());
    // Eq. 1.4 typed independently.
    const double dx = x - kMedialCentre.x(), dy = y - kMedialCentre.y();
    EXPECT_NEAR(hs.value,
                -std::sqrt(kMedialRadius * kMedialRadius - dx * dx - dy * dy) + kMedialCentre.z(),
                1e-16);
  }
}

TEST(SphereCap, GradientAndHessianMatchCentralDifferences) {
  const SphereCap cap(kMedialCentre, kMedialRadius);
  std::mt19937 rng(12);
  const double h = 1e-7;  // m
  for (int s = 0; s < 100; ++s) {
    double x, y;
    RandomFootprintPoint(rng, kMedialCentre, kMedialRadius, 0.9, &x, &y);
    const HeightSample c = Eval(cap, x, y);
    const HeightSample xp = Eval(cap, x + h, y), xm = Eval(cap, x - h, y);
    const HeightSample yp = Eval(cap, x, y + h), ym = Eval(cap, x, y - h);
    const double gx = (xp.value - xm.value) / (2 * h);
    const double gy = (yp.value - ym.value) / (2 * h);
    const double gscale = 1.0 + std::hypot(c.gradient[0], c.gradient[1]);
    EXPECT_NEAR(c.gradient[0], gx, 1e-7 * gscale);
    EXPECT_NEAR(c.gradient[1], gy, 1e-7 * gscale);
    // Hessian from differences of the (separately checked) gradient.
    const double hxx = (xp.gradient[0] - xm.gradient[0]) / (2 * h);
    const double hxy_from_x = (xp.gradient[1] - xm.gradient[1]) / (2 * h);
    const double hxy_from_y = (yp.gradient[0] - ym.gradient[0]) / (2 * h);
    const double hyy = (yp.gradient[1] - ym.gradient[1]) / (2 * h);
    const double hscale = std::abs(c.hessian[0]) + std::abs(c.hessian[1]) + std::abs(c.hessian[2]);
    EXPECT_NEAR(c.hessian[0], hxx, 1e-6 * hscale);
    EXPECT_NEAR(c.hessian[1], hxy_from_x, 1e-6 * hscale);
    EXPECT_NEAR(c.hessian[1], hxy_from_y, 1e-6 * hscale);
    EXPECT_NEAR(c.hessian[2], hyy, 1e-6 * hscale);
  }
}

TEST(SphereCap, RefusesPointsOutsideTheFootprintAndOnTheRim) {
  const SphereCap cap(kMedialCentre, kMedialRadius);
  HeightSample s;
  for (int k = 0; k < 16; ++k) {
    const double theta = 2.0 * kPi * k / 16.0;
    const double cx = std::cos(theta), sy = std::sin(theta);
    // On the rim.
    EXPECT_FALSE(cap.Evaluate(kMedialCentre.x() + kMedialRadius * cx,
                              kMedialCentre.y() + kMedialRadius * sy, &s))
        << "rim, theta = " << theta;
    // Outside.
    for (double f : {1.001, 1.5, 10.0}) {
      EXPECT_FALSE(cap.Evaluate(kMedialCentre.x() + f * kMedialRadius * cx,
                                kMedialCentre.y() + f * kMedialRadius * sy, &s))
          << "outside, factor " << f << ", theta = " << theta;
    }
  }
  // Exactly on the rim in exact arithmetic: sphere centred at the origin, (r, 0).
  const SphereCap origin_cap(Vector3d::Zero(), 0.02);
  EXPECT_FALSE(origin_cap.Evaluate(0.02, 0.0, &s));
  EXPECT_FALSE(origin_cap.Evaluate(0.0, -0.02, &s));
  // And inside it is accepted.
  EXPECT_TRUE(origin_cap.Evaluate(0.0, 0.0, &s));
  EXPECT_DOUBLE_EQ(s.value, -0.02);
}

TEST(SphereCap, RejectsNonPositiveRadius) {
  EXPECT_THROW(SphereCap(kMedialCentre, 0.0), InputError);
  EXPECT_THROW(SphereCap(kMedialCentre, -0.01), InputError);
}

TEST(PlaneSurface, UnitNormalAndOffsetAreConsistentWithPointsOnThePlane) {
  // The chapter's medial plateau (docs/model.md §3), plus a y slope for generality.
  for (double slope_y : {0.0, 0.12}) {
    const double m = 0.358, c = 0.213;
    const PlaneSurface plane(m, slope_y, c);
    const Vector3d n = plane.UnitNormal();
    const double d = plane.NormalOffset();
    EXPECT_NEAR(n.norm(), 1.0, 1e-15);
    EXPECT_GT(n.z(), 0.0);  // towards +z (the femur for a tibial plateau)
    if (slope_y == 0.0) {
      // docs/model.md §3: n̂′ = (−m, 0, 1)/sqrt(1 + m²), d = c/sqrt(1 + m²).
      const double s = std::sqrt(1.0 + m * m);
      EXPECT_NEAR(n.x(), -m / s, 1e-15);
      EXPECT_NEAR(n.y(), 0.0, 1e-15);
      EXPECT_NEAR(n.z(), 1.0 / s, 1e-15);
      EXPECT_NEAR(d, c / s, 1e-15);
    }
    std::mt19937 rng(13);
    std::uniform_real_distribution<double> u(-0.05, 0.05);
    Vector3d first = Vector3d::Zero();
    for (int s = 0; s < 50; ++s) {
      const double x = u(rng), y = u(rng);
      const HeightSample hs = Eval(plane, x, y);
      EXPECT_NEAR(hs.value, m * x + slope_y * y + c, 1e-16);
      EXPECT_EQ(hs.gradient[0], m);
      EXPECT_EQ(hs.gradient[1], slope_y);
      EXPECT_EQ(hs.hessian[0], 0.0);
      EXPECT_EQ(hs.hessian[1], 0.0);
      EXPECT_EQ(hs.hessian[2], 0.0);
      const Vector3d p(x, y, hs.value);
      EXPECT_NEAR(n.dot(p), d, 1e-15);
      if (s == 0) first = p;
      EXPECT_NEAR(n.dot(p - first), 0.0, 1e-15);
      // A point above the plane along +z has n·p > d.
      EXPECT_GT(n.dot(p + Vector3d(0, 0, 1e-3)), d);
    }
  }
}

TEST(EvaluateHeight, JetDerivativesFollowTheChainRule) {
  // x(θ) = x0 + Σ θ_k a_k, y(θ) = y0 + Σ θ_k b_k with random directions; the Jet parts of
  // h and ∇h must equal central differences along each direction.
  constexpr int N = 3;
  using J = ceres::Jet<double, N>;
  const SphereCap cap(kMedialCentre, kMedialRadius);
  const PlaneSurface plane(-0.341, 0.05, 0.2129);
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> dir(-1.0, 1.0);
  const double h = 1e-7;
  for (const HeightField* surface : {static_cast<const HeightField*>(&cap),
                                     static_cast<const HeightField*>(&plane)}) {
    for (int s = 0; s < 50; ++s) {
      double x0, y0;
      RandomFootprintPoint(rng, kMedialCentre, kMedialRadius, 0.85, &x0, &y0);
      J x(x0), y(y0);
      for (int k = 0; k < N; ++k) {
        x.v[k] = dir(rng);
        y.v[k] = dir(rng);
      }
      J value, gradient[2];
      ASSERT_TRUE(EvaluateHeight(*surface, x, y, &value, gradient));
      const HeightSample c = Eval(*surface, x0, y0);
      EXPECT_EQ(value.a, c.value);
      EXPECT_EQ(gradient[0].a, c.gradient[0]);
      EXPECT_EQ(gradient[1].a, c.gradient[1]);
      for (int k = 0; k < N; ++k) {
        const HeightSample p = Eval(*surface, x0 + h * x.v[k], y0 + h * y.v[k]);
        const HeightSample m = Eval(*surface, x0 - h * x.v[k], y0 - h * y.v[k]);
        const double dvalue = (p.value - m.value) / (2 * h);
        const double dgx = (p.gradient[0] - m.gradient[0]) / (2 * h);
        const double dgy = (p.gradient[1] - m.gradient[1]) / (2 * h);
        EXPECT_NEAR(value.v[k], dvalue, 1e-7 * (1.0 + std::abs(dvalue))) << surface->Describe();
        EXPECT_NEAR(gradient[0].v[k], dgx, 1e-6 * (1.0 + std::abs(dgx))) << surface->Describe();
        EXPECT_NEAR(gradient[1].v[k], dgy, 1e-6 * (1.0 + std::abs(dgy))) << surface->Describe();
      }
    }
  }
}

TEST(EvaluateHeight, JetAndDoubleVersionsRefuseOutsideTheFootprint) {
  using J = ceres::Jet<double, 2>;
  const SphereCap cap(kMedialCentre, kMedialRadius);
  const double x = kMedialCentre.x() + 1.2 * kMedialRadius, y = kMedialCentre.y();
  J value, gradient[2];
  EXPECT_FALSE(EvaluateHeight(cap, J(x, 0), J(y, 1), &value, gradient));
  double v, g[2];
  EXPECT_FALSE(EvaluateHeight(cap, x, y, &v, g));
  EXPECT_TRUE(EvaluateHeight(cap, kMedialCentre.x(), kMedialCentre.y(), &v, g));
  EXPECT_NEAR(v, kMedialCentre.z() - kMedialRadius, 1e-16);
}

}  // namespace
}  // namespace kneedyn
