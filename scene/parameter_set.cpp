// A parameter set file: body, gravity, compartments, ligaments, reference pose and the
// chapter's initial guesses (reference-data/scenes/README.md, "Parameter sets").
#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn::scene_detail {
namespace {

void ParseLigamentTable(const Field& ligs, ParameterSet* ps) {
  const std::vector<const char*>& keys = KeysOf("parameter_set.ligaments[]");
  std::vector<std::string> columns;  // ColumnSafeName of each ligament read so far
  for (size_t i = 0; i < ligs.Size(); ++i) {
    const Field f = ligs.Item(i);
    f.Keys(keys);
    Ligament lig;
    lig.name = f.Required("name").Name(/*element=*/true);
    lig.p_FoA_F = f.Required("femoral_mm").Vec3() * kMPerMm;
    lig.p_ToB_T = f.Required("tibial_mm").Vec3() * kMPerMm;
    lig.k_linear = f.Required("k_linear_N_mm").Positive() * kMmPerM;  // N/mm -> N/m
    lig.k_parabolic_published =
        f.Required("k_parabolic_N_mm2").Positive() * kMmPerM * kMmPerM;  // N/mm² -> N/m²
    lig.extension_ratio = f.Required("extension_ratio").Range(0.5, 2.0);
    const std::string column = ColumnSafeName(lig.name);
    for (size_t j = 0; j < ps->ligaments.size(); ++j) {
      const Ligament& other = ps->ligaments[j];
      if (other.name == lig.name) f.Required("name").Fail("duplicate ligament name");
      if (columns[j] == column) {
        f.Required("name").Fail("gives the same output column as element '" + other.name + "'");
      }
    }
    if (ps->ligaments.size() >= 64) ligs.Fail("at most 64 elements");
    ps->ligaments.push_back(lig);
    columns.push_back(column);
  }
}

// Angles and y0 given; x0 and z0 from the contact conditions (the model builder).
void ParseReferencePose(const Field& top, const std::string& path, ParameterSet* ps) {
  const Field ref = top.Required("reference_pose");
  ref.Keys(KeysOf("parameter_set.reference_pose"));
  ReferencePoseDescription d;
  d.alpha = DegToRad(ref.Required("alpha_deg").Range(-kMaxAngleDeg, kMaxAngleDeg));
  d.beta = DegToRad(ref.Required("beta_deg").Range(-kMaxAngleDeg, kMaxAngleDeg));
  d.gamma = DegToRad(ref.Required("gamma_deg").Range(-kMaxAngleDeg, kMaxAngleDeg));
  d.y0 = MmToM(ref.Required("y0_mm").Range(-kMaxLengthMm, kMaxLengthMm));
  if (IsAtJcsSingularity(std::sin(d.beta))) {
    ref.Required("beta_deg").Fail("puts the reference pose at the JCS singularity (sin beta = 0)");
  }
  const auto med = ps->compartments.find("medial");
  const auto lat = ps->compartments.find("lateral");
  if (med == ps->compartments.end() || lat == ps->compartments.end()) {
    Throw<InputError>("LoadScene", EchoPath(path), ": parameter set lacks 'compartments.",
                      med == ps->compartments.end() ? "medial" : "lateral",
                      "': the reference pose is defined from both 'compartments.medial' and 'compartments.lateral'");
  }
  d.medial = med->second;
  d.lateral = lat->second;
  try {
    ps->reference_q = SolveReferencePose(d);
  } catch (const InputError& e) {
    ref.Fail(e.what());
  }
}

void ParseChapterGuesses(const Field& top, ParameterSet* ps) {
  if (!top.Has("chapter_initial_guesses")) return;
  const Field g = top.Required("chapter_initial_guesses");
  g.Keys(KeysOf("parameter_set.chapter_initial_guesses"));
  for (Compartment compartment : {Compartment::kMedial, Compartment::kLateral}) {
    const char* name = CompartmentName(compartment);
    if (!g.Has(name)) continue;
    const Field c = g.Required(name);
    c.Keys(KeysOf("parameter_set.chapter_initial_guesses.COMPARTMENT"));
    ChapterContactGuess cg;
    const std::array<double, 2> femoral_mm = c.Required("femoral_xy_mm").Vec2();
    cg.femoral_xy = {MmToM(femoral_mm[0]), MmToM(femoral_mm[1])};
    if (c.Has("tibial_xy_mm")) {
      const std::array<double, 2> tibial_mm = c.Required("tibial_xy_mm").Vec2();
      cg.tibial_xy = std::array<double, 2>{MmToM(tibial_mm[0]), MmToM(tibial_mm[1])};
    }
    cg.normal_force = c.Required("normal_force_N").Range(-kMaxForceN, kMaxForceN);
    ps->chapter_guesses[static_cast<int>(compartment)] = cg;
  }
}

}  // namespace

ParameterSet LoadParameterSet(const std::string& path) {
  const Field top = ParseYaml(ReadInputFile(path, "parameter set"), path);
  top.Keys(KeysOf("parameter_set"));
  ParameterSet ps;
  ps.file = path;
  ps.name = top.Required("name").Name();
  if (top.Has("description")) top.Required("description").String();
  const Field body = top.Required("body");
  body.Keys(KeysOf("parameter_set.body"));
  ps.mass = body.Required("mass_kg").Range(kMinMassKg, kMaxMassKg);
  ps.inertia_T = body.Required("principal_inertia_kg_m2").Vec3(1e3);
  for (int i = 0; i < 3; ++i) {
    if (!(ps.inertia_T(i) > 0.0)) body.Required("principal_inertia_kg_m2").Item(i).Fail("must be > 0");
  }
  const Field grav = top.Required("gravity");
  grav.Keys(KeysOf("parameter_set.gravity"));
  ps.g = grav.Required("magnitude_m_s2").NonNegative(100.0);
  ps.gravity_direction_F = grav.Required("direction_F").Vec3(1e3);
  if (!(ps.gravity_direction_F.norm() > 0.0)) grav.Required("direction_F").Fail("must be a non-zero vector");
  const Field comps = top.Required("compartments");
  comps.Keys(KeysOf("parameter_set.compartments"));
  for (const char* name : {"medial", "lateral"}) {
    if (comps.Has(name)) ps.compartments[name] = ParseCompartment(comps.Required(name));
  }
  ParseLigamentTable(top.Required("ligaments"), &ps);
  ParseReferencePose(top, path, &ps);
  ParseChapterGuesses(top, &ps);
  return ps;
}

}  // namespace kneedyn::scene_detail
