#include "solver/ligament.hpp"

namespace kneedyn {

double LigamentPotential(const Ligament& lig, double length) {
  const double L0 = lig.slack_length;
  const double x = length - L0;  // elongation, m
  if (x <= 0.0) return 0.0;
  const double x_toe = 2.0 * kLigamentToeStrain * L0;
  if (x <= x_toe) return lig.k_parabolic * x * x * x / 3.0;
  const double e1L0 = kLigamentToeStrain * L0;
  // ∫ k_lin (s − ε1 L0) ds from x_toe to x, with s the elongation.
  return lig.k_parabolic * x_toe * x_toe * x_toe / 3.0 +
         0.5 * lig.k_linear * ((x - e1L0) * (x - e1L0) - (x_toe - e1L0) * (x_toe - e1L0));
}

}  // namespace kneedyn
