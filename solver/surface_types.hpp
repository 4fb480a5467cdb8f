// Every surface type, one line each (with its #include). The scene loader offers the scene
// types under their kSceneType and reads them by their kSceneParameters (surface_parameters.hpp,
// scene/surfaces.cpp); the key table takes their keys from here (scene/scene_keys.cpp); the
// extended-precision references evaluate the charts of all of them in wide scalars
// (surface_wide.hpp); and tests/surface_types_test.cpp runs its conformance checks on each
// scene type.
#pragma once

#include <type_traits>

#include "solver/ellipsoid_cap.hpp"
#include "solver/height_field.hpp"  // SphereCap, PlaneSurface
#include "solver/oriented_plane.hpp"
#include "solver/polynomial_surface.hpp"

namespace kneedyn {

template <typename... Surfaces>
struct SurfaceTypeList {};

// The types a scene's `type:` names, in the order the loader's messages list them.
using SceneSurfaceTypes = SurfaceTypeList<SphereCap, PlaneSurface, EllipsoidCap, PolynomialSurface>;

// Types the solver builds itself: OrientedPlane, the patellar facets (the `patella:` section).
using SolverOnlySurfaceTypes = SurfaceTypeList<OrientedPlane>;

// Calls visit(tag) for each type of a list, in order; the tag's member alias `type` is the
// surface type.
template <typename Surface>
struct SurfaceTypeTag {
  using type = Surface;
};
template <typename... Surfaces, typename Visit>
void ForEachSurfaceType(SurfaceTypeList<Surfaces...>, Visit&& visit) {
  (visit(SurfaceTypeTag<Surfaces>{}), ...);
}

}  // namespace kneedyn
