// The regular charts of every surface type in a wide scalar T (long double, quadruple: the
// extended-precision references, benchmarks/extended_reference.hpp), each by the surface's
// own template, of which its double EvaluateChart is the instance for double (so there is
// one formula per surface). Included by the translation units that instantiate the physics
// for a wide scalar (EvaluateChart, height_field.hpp, declares EvaluateChartWide).
#pragma once

#include "solver/ellipsoid_cap.hpp"
#include "solver/error.hpp"
#include "solver/height_field.hpp"
#include "solver/oriented_plane.hpp"
#include "solver/polynomial_surface.hpp"

namespace kneedyn {

template <typename T>
bool EvaluateHeightWide(const HeightField& surface, const T& x, const T& y, HeightSampleTpl<T>* sample) {
  if (const auto* plane = dynamic_cast<const PlaneSurface*>(&surface)) return plane->HeightTpl(x, y, sample);
  if (const auto* polynomial = dynamic_cast<const PolynomialSurface*>(&surface)) {
    return polynomial->HeightTpl(x, y, sample);
  }
  Throw<SolverError>("EvaluateHeight", surface.Describe(), " has no height-field chart beyond double precision (the "
                     "regular chart has: EvaluateChartWide)");
}

template <typename T>
bool EvaluateChartWide(const HeightField& surface, const T& u, const T& v, ChartSampleTpl<T>* sample) {
  if (const auto* sphere = dynamic_cast<const SphereCap*>(&surface)) return sphere->ChartTpl(u, v, sample);
  if (const auto* plane = dynamic_cast<const OrientedPlane*>(&surface)) return plane->ChartTpl(u, v, sample);
  if (const auto* cap = dynamic_cast<const EllipsoidCap*>(&surface)) return cap->ChartTpl(u, v, sample);
  if (dynamic_cast<const PlaneSurface*>(&surface) == nullptr && dynamic_cast<const PolynomialSurface*>(&surface) == nullptr) {
    Throw<SolverError>("EvaluateChart", surface.Describe(), " has no chart beyond double precision (a surface type "
                       "evaluates a wide scalar through its ChartTpl or HeightTpl; solver/surface_wide.hpp)");
  }
  HeightSampleTpl<T> height;  // the default chart of a height field, (u, v) = (x, y)
  if (!EvaluateHeightWide(surface, u, v, &height)) return false;
  HeightFieldChart(u, v, height, sample);
  return true;
}

}  // namespace kneedyn
