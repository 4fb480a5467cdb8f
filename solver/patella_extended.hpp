// The patella's equilibrium (docs/model.md §12; chapter §1.7, Eq. 1.63) in a scalar wider
// than double (long double, quadruple: the extended-precision references,
// benchmarks/extended_reference.hpp). The 17 equations are the one PatellaResiduals<T> of
// patella.hpp, evaluated in T; only the solve differs from the double one:
//
//   x_0     = the double solution x* (SolvePatella, with its continuation and warm start)
//   x_{k+1} = x_k − J⁻¹ r_T(x_k)        (residual in T, J = ∂r/∂x of the double solve's LU)
//
// i.e. Newton with a frozen Jacobian, or iterative refinement. J is accurate to ~1e-16 of
// itself and x* to round-off, so each iteration multiplies the error by ~cond(J)·1e-16 and
// two or three reach the precision of T. The correction is solved in double: it is ~1e-16
// of x and needs no more than 16 digits of its own.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "solver/error.hpp"
#include "solver/patella.hpp"

namespace kneedyn {

// The equilibrium's unknowns x (PatellaUnknown) in T at the tuberosity position R_a (F, m),
// warm-started and updated as SolvePatella does (*guess: the double solution). Returns the
// number of refinement iterations; throws SolverError naming `caller` when the refinement
// does not reach max |Δx_i| ≤ 8 ε_T (1 + |x_i|) within 12 iterations.
template <typename T>
int SolvePatellaExtended(const Patella& patella, const Vector3<T>& tuberosity_F, const char* caller,
                         PatellaGuess* guess, T x[kPatellaUnknowns]) {
  using std::abs;
  Vector3d tuberosity_d;
  for (int k = 0; k < 3; ++k) tuberosity_d(k) = static_cast<double>(tuberosity_F(k));
  Eigen::PartialPivLU<PatellaJacobian> lu;
  SolvePatella(patella, tuberosity_d, caller, guess, &lu);
  for (int i = 0; i < kPatellaUnknowns; ++i) x[i] = T(guess->x[i]);
  const T eps = std::numeric_limits<T>::epsilon();
  constexpr int kMaxRefinements = 12;
  T r[kPatellaUnknowns];
  Eigen::Matrix<double, kPatellaUnknowns, 1> r_d;
  for (int iteration = 1; iteration <= kMaxRefinements; ++iteration) {
    if (!PatellaResiduals(patella, tuberosity_F, x, r)) {
      Throw<SolverError>(caller, "the patella's extended-precision refinement left a facet's chart at iteration ",
                         iteration, " (docs/model.md §12)");
    }
    for (int i = 0; i < kPatellaUnknowns; ++i) r_d(i) = static_cast<double>(r[i]);
    const Eigen::Matrix<double, kPatellaUnknowns, 1> dx = -lu.solve(r_d);
    bool converged = true;
    for (int i = 0; i < kPatellaUnknowns; ++i) {
      x[i] += T(dx(i));
      if (!(std::abs(dx(i)) <= 8.0 * static_cast<double>(eps) * (1.0 + std::abs(static_cast<double>(x[i]))))) {
        converged = false;
      }
    }
    if (converged) return iteration;
  }
  Throw<SolverError>(caller, "the patella's extended-precision refinement did not reach 8 eps (",
                     static_cast<double>(eps), ") in ", kMaxRefinements,
                     " iterations at the tuberosity position (", MToMm(tuberosity_d.x()), ", ", MToMm(tuberosity_d.y()),
                     ", ", MToMm(tuberosity_d.z()), ") mm in F (docs/model.md §12)");
}

// PatellarTendonForce (patella.hpp) for a wide scalar: tension F_t = τ_t F_Q(t) (N) and the
// tendon's pull on the tibia at the tuberosity, F_t (R_t − R_a)/|R_t − R_a| (F components).
template <typename T>
void PatellarTendonForceExtended(const Patella& patella, double t, const PoseTpl<T>& tibia, PatellaGuess* guess,
                                 T* tension, Vector3<T>* force_F) {
  const Vector3<T> tuberosity_F = TuberosityInF(patella, tibia);
  T x[kPatellaUnknowns];
  SolvePatellaExtended(patella, tuberosity_F, "PatellarTendonForce", guess, x);
  const PoseTpl<T> pose = PatellaPose(x);
  const Vector3<T> apex_F = pose.PointInF(patella.apex_P.template cast<T>());
  *tension = x[kPatellaTendonRatio] * T(QuadricepsMagnitude(patella.quadriceps, t));
  const Vector3<T> span_F = apex_F - tuberosity_F;
  *force_F = *tension * span_F / span_F.norm();
}

}  // namespace kneedyn
