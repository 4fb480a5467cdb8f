// Third derivatives of every surface type's regular chart (height_field.hpp:
// EvaluateChartThird). They enter only the derivative of the contact rate term κ (curvature
// rate) with respect to the state: the exact ∂q̈/∂(q, q̇) of the hidden-constraint solve on
// general surface pairs (ConstrainedAccelerationJacobian, constrained_dynamics.hpp).
#include "solver/ellipsoid_cap.hpp"
#include "solver/error.hpp"
#include "solver/height_field.hpp"
#include "solver/oriented_plane.hpp"
#include "solver/polynomial_surface.hpp"

namespace kneedyn {
namespace {

// s(u, v) = (sin u, cos u sin v, −cos u cos v) of UnitSphereChart (height_field.cpp), same
// domain: s_uu = −s, so s_uuu = −s_u and s_uuv = −s_v; s_vvv = −s_v.
bool UnitSphereChartThird(double u, double v, ChartThirdSample* s) {
  ChartSample second;
  if (!UnitSphereChart(u, v, &second)) return false;
  const double su = std::sin(u), cu = std::cos(u), sv = std::sin(v), cv = std::cos(v);
  s->p_uuu = -second.p_u;
  s->p_uuv = -second.p_v;
  s->p_uvv = Vector3d(0.0, su * sv, -su * cv);
  s->p_vvv = Vector3d(0.0, -cu * cv, -cu * sv);
  return true;
}

// The third derivatives of the cap P = C + L s (MappedUnitSphereChart, height_field.hpp).
template <typename LinearMap>
bool MappedUnitSphereChartThird(double u, double v, const LinearMap& map, ChartThirdSample* s) {
  if (!UnitSphereChartThird(u, v, s)) return false;
  s->p_uuu = map(s->p_uuu);
  s->p_uuv = map(s->p_uuv);
  s->p_uvv = map(s->p_uvv);
  s->p_vvv = map(s->p_vvv);
  return true;
}

}  // namespace

bool HeightField::EvaluateChartThird(double, double, ChartThirdSample*) const {
  Throw<SolverError>("HeightField::EvaluateChartThird", "the surface ", Describe(),
                     " gives no third chart derivatives (rule: every surface type used with the exact "
                     "Jacobian of the hidden constraint overrides EvaluateChartThird)");
}

bool SphereCap::EvaluateChartThird(double u, double v, ChartThirdSample* s) const {
  const auto scale = [this](const Vector3d& x) -> Vector3d { return radius_ * x; };
  return MappedUnitSphereChartThird(u, v, scale, s);
}

bool EllipsoidCap::EvaluateChartThird(double u, double v, ChartThirdSample* s) const {
  const auto map = [this](const Vector3d& x) -> Vector3d { return A_ * x; };
  return MappedUnitSphereChartThird(u, v, map, s);
}

// Height-field chart (x, y, h) of a plane: linear.
bool PlaneSurface::EvaluateChartThird(double, double, ChartThirdSample* s) const {
  *s = ChartThirdSample();
  return true;
}

// P = d n̂ + u e1 + v e2: linear.
bool OrientedPlane::EvaluateChartThird(double, double, ChartThirdSample* s) const {
  *s = ChartThirdSample();
  return true;
}

// Height-field chart (x, y, h): P_uuu = (0, 0, h_xxx), … Third derivatives in (ξ, η), turned
// to the bone's (x, y) as the Hessian is (PolynomialSurface::Evaluate):
// ∂_x = C ∂_ξ − S ∂_η, ∂_y = S ∂_ξ + C ∂_η.
bool PolynomialSurface::EvaluateChartThird(double x, double y, ChartThirdSample* s) const {
  const double dx = x - origin_.x(), dy = y - origin_.y();
  const double xi = cos_ * dx + sin_ * dy, eta = -sin_ * dx + cos_ * dy;
  double px[kMaxDegree + 1], py[kMaxDegree + 1];
  px[0] = py[0] = 1.0;
  for (int i = 1; i <= kMaxDegree; ++i) {
    px[i] = px[i - 1] * xi;
    py[i] = py[i - 1] * eta;
  }
  // local[a + b + c] over (ξ, η) indices: local[n] = ∂³h/∂ξ^(3−n)∂η^n.
  double local[4] = {0.0, 0.0, 0.0, 0.0};
  for (int i = 0; i <= kMaxDegree; ++i) {
    for (int j = 0; i + j <= kMaxDegree; ++j) {
      const double c = c_[i][j];
      if (c == 0.0) continue;
      for (int n = 0; n <= 3; ++n) {  // n derivatives in η, 3 − n in ξ
        const int a = 3 - n;
        if (i < a || j < n) continue;
        double factor = c;
        for (int r = 0; r < a; ++r) factor *= i - r;
        for (int r = 0; r < n; ++r) factor *= j - r;
        local[n] += factor * px[i - a] * py[j - n];
      }
    }
  }
  const double D[2][2] = {{cos_, -sin_}, {sin_, cos_}};  // ∂_{x_k} = Σ_m D[k][m] ∂_{ξ_m}
  auto third = [&](int i, int j, int k) {
    double sum = 0.0;
    for (int a = 0; a < 2; ++a) {
      for (int b = 0; b < 2; ++b) {
        for (int c = 0; c < 2; ++c) sum += D[i][a] * D[j][b] * D[k][c] * local[a + b + c];
      }
    }
    return sum;
  };
  *s = ChartThirdSample();
  s->p_uuu(2) = third(0, 0, 0);
  s->p_uuv(2) = third(0, 0, 1);
  s->p_uvv(2) = third(0, 1, 1);
  s->p_vvv(2) = third(1, 1, 1);
  return true;
}

}  // namespace kneedyn
