#include "scene/internal/scene_keys.hpp"

#include <deque>
#include <stdexcept>
#include <string>
#include <tuple>

#include "solver/surface_types.hpp"

namespace kneedyn {
namespace {

const std::vector<const char*>& Find(const std::vector<SceneKeyTable>& table, std::string_view name) {
  for (const SceneKeyTable& t : table) {
    if (name == t.mapping) return t.entries;
  }
  throw std::logic_error("scene key table: no entry '" + std::string(name) + "'");
}

// "surface.<type>" for each scene surface type (solver/surface_types.hpp): "type" and its
// parameters' keys, in the order the type declares them.
std::vector<SceneKeyTable> SurfaceTypeKeys() {
  static std::deque<std::string> names;  // the mappings' names, alive as long as the table
  std::vector<SceneKeyTable> out;
  ForEachSurfaceType(SceneSurfaceTypes{}, [&out](auto tag) {
    using Surface = typename decltype(tag)::type;
    std::vector<const char*> keys = {"type"};
    std::apply([&keys](const auto&... parameter) { (keys.push_back(parameter.key), ...); }, Surface::kSceneParameters);
    out.push_back({names.emplace_back(std::string("surface.") + Surface::kSceneType).c_str(), std::move(keys)});
  });
  return out;
}

std::vector<const char*> SurfaceTypeNames() {
  std::vector<const char*> out;
  ForEachSurfaceType(SceneSurfaceTypes{}, [&out](auto tag) { out.push_back(decltype(tag)::type::kSceneType); });
  return out;
}

}  // namespace

const std::vector<SceneKeyTable>& SceneMappingKeys() {
  static const std::vector<SceneKeyTable> table = [] {
    std::vector<SceneKeyTable> t = {
      // A scene file.
      {"scene", {"name", "description", "parameter_set", "body", "angular_velocity_map", "ligament_law", "ligaments",
                 "ligament_stiffness_scale", "ligament_parameters", "contacts", "surfaces", "gravity", "pulse",
                 "constant_load", "initial_state", "end", "output", "patella"}},
      {"scene.body", {"mass_kg", "principal_inertia_kg_m2"}},
      {"scene.ligament_parameters.NAME", {"k_linear_N_mm", "k_parabolic_N_mm2", "extension_ratio"}},
      {"scene.surfaces", {"medial", "lateral"}},
      {"scene.gravity", {"enabled", "direction_F", "magnitude_m_s2"}},
      {"scene.pulse", {"shape", "amplitude_N", "duration_s", "direction_T"}},
      {"scene.constant_load", {"force_F_N", "torque_T_N_m"}},
      {"scene.patella", {"trochlea_medial", "trochlea_lateral", "facet_medial", "facet_lateral", "apex_P_mm",
                         "base_P_mm", "tuberosity_T_mm", "tendon_length_mm", "quadriceps", "facet_liftoff"}},
      {"scene.patella.trochlea", {"centre_mm", "radius_mm"}},
      {"scene.patella.facet", {"normal_P", "offset_mm"}},
      {"scene.patella.quadriceps", {"shape", "magnitude_N", "baseline_N", "duration_s", "direction_F"}},
      {"scene.initial_state", {"pose", "coordinates", "velocities", "hold", "guesses", "normal_force_guesses_N",
                               "contact_guess_offset_mm", "origin", "start"}},
      {"scene.initial_state.coordinates", {"x0_mm", "y0_mm", "z0_mm", "alpha_deg", "beta_deg", "gamma_deg"}},
      {"scene.initial_state.velocities",
       {"x0_mm_s", "y0_mm_s", "z0_mm_s", "alpha_deg_s", "beta_deg_s", "gamma_deg_s"}},
      {"scene.initial_state.normal_force_guesses_N", {"medial", "lateral"}},
      {"scene.end", {"flexion_deg", "time_s"}},
      {"scene.output", {"interval_s"}},
      // A compartment's surfaces (parameter set, or scene.surfaces.medial/lateral); each
      // surface type's keys are added below from the type itself.
      {"compartment", {"femoral_surface", "tibial_surface"}},
      // A parameter set.
      {"parameter_set", {"name", "description", "body", "gravity", "compartments", "ligaments", "reference_pose",
                         "chapter_initial_guesses"}},
      {"parameter_set.body", {"mass_kg", "principal_inertia_kg_m2"}},
      {"parameter_set.gravity", {"magnitude_m_s2", "direction_F"}},
      {"parameter_set.compartments", {"medial", "lateral"}},
      {"parameter_set.ligaments[]",
       {"name", "femoral_mm", "tibial_mm", "k_linear_N_mm", "k_parabolic_N_mm2", "extension_ratio"}},
      {"parameter_set.reference_pose", {"alpha_deg", "beta_deg", "gamma_deg", "y0_mm"}},
      {"parameter_set.chapter_initial_guesses", {"medial", "lateral"}},
      {"parameter_set.chapter_initial_guesses.COMPARTMENT", {"femoral_xy_mm", "tibial_xy_mm", "normal_force_N"}},
    };
    for (SceneKeyTable& surface : SurfaceTypeKeys()) t.push_back(std::move(surface));
    return t;
  }();
  return table;
}

const std::vector<SceneKeyTable>& SceneFieldValues() {
  static const std::vector<SceneKeyTable> table = {
      {"scene.ligament_law", {"published", "c1_continuous"}},
      {"scene.angular_velocity_map", {"exact", "printed_eq_1_20b"}},
      {"scene.ligaments", {"all", "none"}},  // or a list of element names
      {"scene.contacts[]", {"medial", "lateral"}},
      // As solver/loads.cpp's ParsePulseShape reads them (checked by tests/scene_test.cpp).
      {"scene.pulse.shape", {"reconstructed", "half_sine", "reconstructed_peak", "damped_sine", "none"}},
      // As solver/patella.cpp's ParseQuadricepsShape reads them.
      {"scene.patella.quadriceps.shape", {"constant", "ramp", "half_sine"}},
      {"surface.type", SurfaceTypeNames()},  // solver/surface_types.hpp
      {"scene.initial_state.pose", {"reference", "explicit", "assemble"}},
      {"scene.initial_state.guesses", {"pose", "chapter"}},
      {"scene.initial_state.origin", {"both_contacts", "medial_contact"}},
      {"scene.initial_state.start", {"consistent", "unprojected"}},
      {"scene.initial_state.hold[]", {"x0", "y0", "z0", "alpha", "beta", "gamma", "x0_dot", "y0_dot", "z0_dot",
                                      "alpha_dot", "beta_dot", "gamma_dot", "velocities"}},
  };
  return table;
}

const std::vector<const char*>& KeysOf(std::string_view mapping) { return Find(SceneMappingKeys(), mapping); }
const std::vector<const char*>& ValuesOf(std::string_view field) { return Find(SceneFieldValues(), field); }

}  // namespace kneedyn
