// The regular charts of every surface type in a wide scalar T (long double, quadruple: the
// extended-precision references, benchmarks/extended_reference.hpp), each by the surface's
// own template, of which its double EvaluateChart is the instance for double (so there is
// one formula per surface). Included by the translation units that instantiate the physics
// for a wide scalar (EvaluateChart, height_field.hpp, declares EvaluateChartWide).
//
// The dispatch runs over the type lists of surface_types.hpp: a type with a ChartTpl template
// evaluates its regular chart; a type with only a HeightTpl template (a height field whose
// regular chart is its height-field chart) evaluates its height. A new type in the list
// needs one of the two (a static_assert says so).
#pragma once

#include <optional>

#include "solver/error.hpp"
#include "solver/height_field.hpp"
#include "solver/surface_types.hpp"

namespace kneedyn {
/// \cond INTERNAL
namespace surface_wide_detail {

template <typename Surface, typename T, typename = void>
struct HasChartTpl : std::false_type {};
template <typename Surface, typename T>
struct HasChartTpl<Surface, T,
                   std::void_t<decltype(std::declval<const Surface&>().ChartTpl(
                       std::declval<const T&>(), std::declval<const T&>(), std::declval<ChartSampleTpl<T>*>()))>>
    : std::true_type {};

template <typename Surface, typename T, typename = void>
struct HasHeightTpl : std::false_type {};
template <typename Surface, typename T>
struct HasHeightTpl<Surface, T,
                    std::void_t<decltype(std::declval<const Surface&>().HeightTpl(
                        std::declval<const T&>(), std::declval<const T&>(), std::declval<HeightSampleTpl<T>*>()))>>
    : std::true_type {};

template <typename Surface>
constexpr bool kDependentFalse = false;

// The chart of `surface` if it is a Surface (nullopt otherwise): true/false as the chart's domain.
template <typename Surface, typename T>
std::optional<bool> ChartIfType(const HeightField& surface, const T& u, const T& v, ChartSampleTpl<T>* sample) {
  const auto* typed = dynamic_cast<const Surface*>(&surface);
  if (typed == nullptr) return std::nullopt;
  if constexpr (HasChartTpl<Surface, T>::value) {
    return typed->ChartTpl(u, v, sample);
  } else if constexpr (HasHeightTpl<Surface, T>::value) {
    HeightSampleTpl<T> height;  // the default chart of a height field, (u, v) = (x, y)
    if (!typed->HeightTpl(u, v, &height)) return false;
    HeightFieldChart(u, v, height, sample);
    return true;
  } else {
    static_assert(kDependentFalse<Surface>, "a surface type needs a ChartTpl or a HeightTpl template (height_field.hpp)");
  }
}

template <typename Surface, typename T>
std::optional<bool> HeightIfType(const HeightField& surface, const T& x, const T& y, HeightSampleTpl<T>* sample) {
  if constexpr (HasHeightTpl<Surface, T>::value) {
    if (const auto* typed = dynamic_cast<const Surface*>(&surface)) return typed->HeightTpl(x, y, sample);
  }
  return std::nullopt;
}

template <typename T, typename... Surfaces>
std::optional<bool> ChartOfListed(SurfaceTypeList<Surfaces...>, const HeightField& surface, const T& u, const T& v,
                                  ChartSampleTpl<T>* sample) {
  std::optional<bool> result;
  ((result = result ? result : ChartIfType<Surfaces>(surface, u, v, sample)), ...);
  return result;
}

template <typename T, typename... Surfaces>
std::optional<bool> HeightOfListed(SurfaceTypeList<Surfaces...>, const HeightField& surface, const T& x, const T& y,
                                   HeightSampleTpl<T>* sample) {
  std::optional<bool> result;
  ((result = result ? result : HeightIfType<Surfaces>(surface, x, y, sample)), ...);
  return result;
}

}  // namespace surface_wide_detail
/// \endcond

template <typename T>
bool EvaluateHeightWide(const HeightField& surface, const T& x, const T& y, HeightSampleTpl<T>* sample) {
  using namespace surface_wide_detail;
  std::optional<bool> result = HeightOfListed(SceneSurfaceTypes{}, surface, x, y, sample);
  if (!result) result = HeightOfListed(SolverOnlySurfaceTypes{}, surface, x, y, sample);
  if (result) return *result;
  Throw<SolverError>("EvaluateHeight", surface.Describe(), " has no height-field chart beyond double precision (the "
                     "regular chart has: EvaluateChartWide)");
}

template <typename T>
bool EvaluateChartWide(const HeightField& surface, const T& u, const T& v, ChartSampleTpl<T>* sample) {
  using namespace surface_wide_detail;
  std::optional<bool> result = ChartOfListed(SceneSurfaceTypes{}, surface, u, v, sample);
  if (!result) result = ChartOfListed(SolverOnlySurfaceTypes{}, surface, u, v, sample);
  if (result) return *result;
  Throw<SolverError>("EvaluateChart", surface.Describe(), " has no chart beyond double precision (a surface type "
                     "evaluates a wide scalar through its ChartTpl or HeightTpl, and is listed in "
                     "solver/surface_types.hpp)");
}

}  // namespace kneedyn
