// Ligament force law (chapter Eqs. 1.14–1.16, Tables 1.1–1.3; docs/model.md §5).
//
//   ε = (L − L0)/L0,  ε1 = 0.03
//   F = 0                          ε ≤ 0
//   F = k_par (L − L0)²            0 < ε ≤ 2 ε1
//   F = k_lin (L − (1 + ε1) L0)    ε > 2 ε1
//
// Departure from the printed Table 1.2 header (docs/model.md §5): the first column is k_lin (N/mm),
// the second k_par (N/mm²). The force acts on the tibia at its attachment, towards the
// femoral attachment.
#pragma once

#include <cmath>

#include "solver/model.hpp"
#include "solver/pose.hpp"

namespace kneedyn {

// Discontinuity locking: the published law jumps at ε = 2ε1, which no Newton iteration
// can straddle. Within a solver phase each element's branch is frozen (its formula
// continued smoothly past the kink); the crossing is an event (events.hpp) after which
// the phase restarts on the other branch.
enum LigamentBranch : signed char {
  kBranchAuto = -1,  // choose by length (the law as written)
  kBranchToe = 0,    // slack or parabolic: F = k_par (L − L0)² for L > L0, else 0
  kBranchLinear = 1  // F = k_lin (L − (1 + ε1) L0)
};

template <typename T>
T LigamentTension(const Ligament& lig, const T& length, LigamentBranch branch = kBranchAuto) {
  const double L0 = lig.slack_length;
  const T elongation = length - L0;
  if (branch == kBranchAuto) {
    branch = ScalarPart(elongation) <= 2.0 * kLigamentToeStrain * L0 ? kBranchToe : kBranchLinear;
  }
  if (branch == kBranchToe) {
    if (ScalarPart(elongation) <= 0.0) return T(0.0);
    return lig.k_parabolic * elongation * elongation;
  }
  return lig.k_linear * (length - (1.0 + kLigamentToeStrain) * L0);
}

// dF/dL of LigamentTension on the same branch (N/m): 2 k_par (L − L0) on the toe (0 when
// slack), k_lin on the linear branch. For exact Jacobians (newton_euler_jacobian.hpp).
inline double LigamentStiffness(const Ligament& lig, double length, LigamentBranch branch = kBranchAuto) {
  const double L0 = lig.slack_length;
  const double elongation = length - L0;
  if (branch == kBranchAuto) {
    branch = elongation <= 2.0 * kLigamentToeStrain * L0 ? kBranchToe : kBranchLinear;
  }
  if (branch == kBranchToe) return elongation <= 0.0 ? 0.0 : 2.0 * lig.k_parabolic * elongation;
  return lig.k_linear;
}

// Length at the kink, (1 + 2ε1) L0 (m).
inline double LigamentKinkLength(const Ligament& lig) {
  return (1.0 + 2.0 * kLigamentToeStrain) * lig.slack_length;
}

// Strain energy stored in the element at length L (J): the integral of the law above, so
// that −dV/dL = −F holds piecewise even where the published law jumps.
double LigamentPotential(const Ligament& lig, double length);
// The same in any scalar type (the double overload calls it).
template <typename T>
T LigamentPotentialTpl(const Ligament& lig, const T& length) {
  const double L0 = lig.slack_length;
  const T x = length - L0;  // elongation, m
  if (x <= 0.0) return T(0.0);
  const double x_toe = 2.0 * kLigamentToeStrain * L0;
  if (x <= x_toe) return lig.k_parabolic * x * x * x / 3.0;
  const double e1L0 = kLigamentToeStrain * L0;
  // ∫ k_lin (s − ε1 L0) ds from x_toe to x, with s the elongation.
  return lig.k_parabolic * x_toe * x_toe * x_toe / 3.0 +
         0.5 * lig.k_linear * ((x - e1L0) * (x - e1L0) - (x_toe - e1L0) * (x_toe - e1L0));
}

// Strain ε = (L − L0)/L0.
inline double LigamentStrain(const Ligament& lig, double length) {
  return (length - lig.slack_length) / lig.slack_length;
}

// Vector from tibial to femoral attachment, in F (m).
template <typename T>
Vector3<T> LigamentSpan_F(const Ligament& lig, const PoseTpl<T>& pose) {
  return lig.p_FoA_F.template cast<T>() - pose.PointInF(lig.p_ToB_T.template cast<T>());
}

}  // namespace kneedyn
