// Scene sections: ligament_law, ligaments, ligament_stiffness_scale, ligament_parameters.
#include <algorithm>

#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn::scene_detail {
namespace {

// "all", "none", or a list of element names.
std::vector<std::string> SelectedNames(const Field& f, const ParameterSet& ps) {
  std::vector<std::string> names;
  if (f.IsScalar()) {
    const std::string s = f.String();
    if (s == "all") {
      for (const Ligament& l : ps.ligaments) names.push_back(l.name);
    } else if (s != "none") {
      f.Fail("must be " + ListOf(ValuesOf("scene.ligaments")) + " or a list of element names");
    }
  } else {
    for (size_t i = 0; i < f.Size(); ++i) names.push_back(f.Item(i).Name(/*element=*/true));
  }
  return names;
}

// Per-element values replacing the parameter set's (before the stiffness scale).
void ApplyLigamentParameters(const Field& p, Ligament* lig) {
  for (const std::string& key : p.Keys()) {
    if (key == "k_linear_N_mm") {
      lig->k_linear = p.Required(key).Positive() * kMmPerM;  // N/mm -> N/m
    } else if (key == "k_parabolic_N_mm2") {
      lig->k_parabolic_published = p.Required(key).Positive() * kMmPerM * kMmPerM;
    } else if (key == "extension_ratio") {
      lig->extension_ratio = p.Required(key).Positive();
    } else {
      p.Required(key).Fail("unknown ligament parameter; expected " +
                           ListOf(KeysOf("scene.ligament_parameters.NAME")));
    }
  }
}

}  // namespace

void ParseLigaments(const Field& top, const ParameterSet& ps, ModelDescription* model) {
  if (top.Has("ligament_law")) {
    const std::string law = top.Required("ligament_law").OneOf(ValuesOf("scene.ligament_law"), "ligament law");
    for (const LigamentLaw l : kLigamentLaws) {
      if (law == LigamentLawName(l)) model->ligament_law = l;
    }
  }
  const Field f = top.Required("ligaments");
  const std::vector<std::string> names = SelectedNames(f, ps);
  double stiffness_scale = 1.0;
  if (top.Has("ligament_stiffness_scale")) {
    stiffness_scale = top.Required("ligament_stiffness_scale").Range(1e-3, 1e3);
  }
  for (size_t i = 0; i < names.size(); ++i) {
    auto it = std::find_if(ps.ligaments.begin(), ps.ligaments.end(),
                           [&](const Ligament& l) { return l.name == names[i]; });
    if (it == ps.ligaments.end()) {
      std::string known;
      for (const Ligament& l : ps.ligaments) known += (known.empty() ? "" : ", ") + l.name;
      f.Item(i).Fail("unknown ligament name; the parameter set has: " + known);
    }
    for (const Ligament& l : model->ligaments) {
      if (l.name == names[i]) f.Item(i).Fail("ligament listed twice");
    }
    Ligament lig = *it;
    if (top.Has("ligament_parameters") && top.Required("ligament_parameters").Has(names[i])) {
      ApplyLigamentParameters(top.Required("ligament_parameters").Required(names[i]), &lig);
    }
    lig.k_linear *= stiffness_scale;
    lig.k_parabolic_published *= stiffness_scale;
    model->ligaments.push_back(lig);
  }
  if (top.Has("ligament_parameters")) {
    const Field p = top.Required("ligament_parameters");
    for (const std::string& key : p.Keys()) {
      if (std::none_of(model->ligaments.begin(), model->ligaments.end(),
                       [&](const Ligament& l) { return l.name == key; })) {
        p.Required(key).Fail("not a ligament element selected by this scene (field 'ligaments')");
      }
    }
  }
}

}  // namespace kneedyn::scene_detail
