#include "solver/ligament.hpp"

namespace kneedyn {

double LigamentPotential(const Ligament& lig, double length) { return LigamentPotentialTpl(lig, length); }

}  // namespace kneedyn
